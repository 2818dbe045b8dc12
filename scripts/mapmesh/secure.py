"""DDS Security for a run (`swarm run --secure`): a run certificate authority, one identity
(certificate and private key) per agent and per feeder, a signed governance document and one
signed permissions document per participant, and a Cyclone config per process that loads the
security plugins with them. Everything is made with openssl in DIR/security; private keys are
0600.

What the documents say:
- governance: only authenticated participants join the domain; discovery, liveliness and every
  topic's data are encrypted and signed, and reads and writes are access-controlled.
- permissions of agent N: publish the agents' topics (maps, status, sightings) only in the
  DDS partition `robotN`; subscribe to everything. Agents publish those topics in their own
  partition and refuse a sample whose robot id is not its writer's partition's, so a peer with
  a valid certificate cannot speak for another robot.
- permissions of the feeder: publish the sensor topics and truth, and links and exchange ticks
  in the DDS partition `feeder` only; subscribe to everything. No agent may publish a sensor
  topic, links or ticks; agents take links and ticks only from the feeder's partition.

A real deployment makes the same files once, keeps the CA key off the robots, and gives each
robot only its own key (docs/SECURITY.md)."""

import datetime
import os
import subprocess
from pathlib import Path

from .run_error import RunError

PLUGIN_DIRS = [Path("/usr/lib/x86_64-linux-gnu/libddsc0debian"), Path("/usr/lib/x86_64-linux-gnu"),
               Path("/usr/lib/aarch64-linux-gnu/libddsc0debian"), Path("/usr/lib")]
PLUGINS = {"auth": "libdds_security_auth.so", "ac": "libdds_security_ac.so", "crypto": "libdds_security_crypto.so"}
ORG = "mapmesh"
AGENT_TOPICS = ["mapmesh/map", "mapmesh/status", "mapmesh/sighting"]
FEEDER_TOPICS = ["mapmesh/odom/*", "mapmesh/scan/*", "mapmesh/truth"]
FEEDER_PARTITION_TOPICS = ["mapmesh/links", "mapmesh/tick"]  # in its partition (topics.h kFeederPartition)
FEEDER_PARTITION = "feeder"


def plugin_paths():
    """The three Cyclone security plugins' paths, or a RunError naming what is missing."""
    found = {}
    for key, name in PLUGINS.items():
        for d in PLUGIN_DIRS:
            if (d / name).exists():
                found[key] = str(d / name)
                break
    missing = [PLUGINS[k] for k in PLUGINS if k not in found]
    if missing:
        raise RunError(f"--secure: Cyclone DDS security plugins not found ({', '.join(missing)}; Debian package "
                       f"libddsc0debian)", 2)
    return found


def _openssl(*args, cwd):
    r = subprocess.run(["openssl", *args], cwd=cwd, capture_output=True, text=True)
    if r.returncode != 0:
        tail = (r.stderr.strip().splitlines() or ["no output"])[-1]
        raise RunError(f"--secure: openssl {args[0]} failed: {tail}", 2)


def _private(path):
    os.chmod(path, 0o600)


def subject(name):
    return f"CN={name},O={ORG}"


def make_ca(directory, name="mapmesh run CA", days=2):
    """A self-signed EC CA: (cert path, key path)."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    key, cert = d / "ca.key", d / "ca.pem"
    _openssl("ecparam", "-name", "prime256v1", "-genkey", "-noout", "-out", str(key), cwd=d)
    _private(key)
    _openssl("req", "-new", "-x509", "-key", str(key), "-out", str(cert), "-days", str(days),
             "-subj", f"/O={ORG}/CN={name}", cwd=d)
    return cert, key


def make_identity(directory, name, ca_cert, ca_key, days=2):
    """A key and a certificate for participant `name` signed by the CA: (cert, key)."""
    d = Path(directory)
    key, csr, cert = d / f"{name}.key", d / f"{name}.csr", d / f"{name}.pem"
    _openssl("ecparam", "-name", "prime256v1", "-genkey", "-noout", "-out", str(key), cwd=d)
    _private(key)
    _openssl("req", "-new", "-key", str(key), "-out", str(csr), "-subj", f"/O={ORG}/CN={name}", cwd=d)
    _openssl("x509", "-req", "-in", str(csr), "-CA", str(ca_cert), "-CAkey", str(ca_key), "-CAcreateserial",
             "-out", str(cert), "-days", str(days), cwd=d)
    csr.unlink()
    return cert, key


def identity_problem(cert, key):
    """What is wrong with an identity, as one line naming its files, or None: the private key
    must be readable by its owner only (mode 0600 or stricter) and be the certificate's (with a
    key that does not match, a participant comes up and every handshake fails)."""
    try:
        mode = os.stat(key).st_mode & 0o7777
    except OSError as e:
        return f"{key}: cannot read the private key ({e.strerror})"
    if mode & 0o077:
        return f"{key}: the private key is readable by others (mode {mode:04o}); chmod 600 it"
    pub = []
    for args in (["x509", "-in", str(cert), "-noout", "-pubkey"], ["pkey", "-in", str(key), "-pubout"]):
        r = subprocess.run(["openssl", *args], capture_output=True, text=True)
        if r.returncode != 0:
            what = "certificate" if args[0] == "x509" else "private key"
            return f"{args[2]}: not a PEM {what}"
        pub.append(r.stdout.strip())
    if pub[0] != pub[1]:
        return f"{key}: the private key does not match the certificate {cert}"
    return None


def sign(directory, xml_text, stem, ca_cert, ca_key):
    """The S/MIME-signed document DIR/stem.p7s of xml_text (DDS Security's signed XML)."""
    d = Path(directory)
    src, out = d / f"{stem}.xml", d / f"{stem}.p7s"
    src.write_text(xml_text)
    _openssl("smime", "-sign", "-text", "-in", str(src), "-out", str(out), "-signer", str(ca_cert),
             "-inkey", str(ca_key), cwd=d)
    return out


def governance_xml(domain):
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-Security/20170801/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains><id>{domain}</id></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>NONE</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
"""


def _topics(names):
    return "".join(f"<topic>{n}</topic>" for n in names)


def permissions_xml(name, domain, publish, partition=None, days=2):
    """Permissions of participant `name`: publish the topics `publish` (in `partition` only when
    given; `publish` may also be a list of (topics, partition) rules), subscribe to every topic in
    every partition, nothing else."""
    now = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0)
    before = (now - datetime.timedelta(hours=1)).strftime("%Y-%m-%dT%H:%M:%S")
    after = (now + datetime.timedelta(days=days)).strftime("%Y-%m-%dT%H:%M:%S")
    rules = publish if publish and isinstance(publish[0], tuple) else [(publish, partition)]

    def rule(topics, part):
        parts = f"<partitions><partition>{part}</partition></partitions>" if part else ""
        return f"<publish><topics>{_topics(topics)}</topics>{parts}</publish>"
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-Security/20170801/omg_shared_ca_permissions.xsd">
  <permissions>
    <grant name="{name}">
      <subject_name>{subject(name)}</subject_name>
      <validity><not_before>{before}</not_before><not_after>{after}</not_after></validity>
      <allow_rule>
        <domains><id>{domain}</id></domains>
        {"".join(rule(t, part) for t, part in rules)}
        <subscribe><topics><topic>*</topic></topics><partitions><partition>*</partition></partitions></subscribe>
        <subscribe><topics><topic>*</topic></topics></subscribe>
      </allow_rule>
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
"""


def security_xml(plugins, ca_cert, cert, key, governance, permissions, perm_ca=None):
    perm_ca = perm_ca or ca_cert

    def uri(p):
        return f"file:{Path(p).resolve()}"

    return f"""<Security>
      <Authentication>
        <Library path="{plugins['auth']}" initFunction="init_authentication"
                 finalizeFunction="finalize_authentication"/>
        <IdentityCA>{uri(ca_cert)}</IdentityCA>
        <IdentityCertificate>{uri(cert)}</IdentityCertificate>
        <PrivateKey>{uri(key)}</PrivateKey>
      </Authentication>
      <AccessControl>
        <Library path="{plugins['ac']}" initFunction="init_access_control"
                 finalizeFunction="finalize_access_control"/>
        <PermissionsCA>{uri(perm_ca)}</PermissionsCA>
        <Governance>{uri(governance)}</Governance>
        <Permissions>{uri(permissions)}</Permissions>
      </AccessControl>
      <Cryptographic>
        <Library path="{plugins['crypto']}" initFunction="init_crypto" finalizeFunction="finalize_crypto"/>
      </Cryptographic>
    </Security>"""


def with_security(base_xml, security):
    """base_xml (a Cyclone config) with `security` inserted as the last child of its Domain."""
    at = base_xml.rfind("</Domain>")
    if at < 0:
        raise RunError("--secure: the Cyclone config has no <Domain> element to add <Security> to", 2)
    return base_xml[:at] + "  " + security + "\n  " + base_xml[at:]


def participant_name(role, rid=None):
    return f"agent{rid}" if role == "agent" else role


class RunSecurity:
    """The run's CA, identities, governance and permissions in DIR/security, and each
    participant's Cyclone config there."""

    def __init__(self, out_dir, domain, base_config_path):
        self.dir = Path(out_dir) / "security"
        self.dir.mkdir(parents=True, exist_ok=True)
        os.chmod(self.dir, 0o700)
        self.domain = domain
        self.base = Path(base_config_path).read_text()
        self.plugins = plugin_paths()
        self.ca_cert, self.ca_key = make_ca(self.dir)
        self.governance = sign(self.dir, governance_xml(domain), "governance", self.ca_cert, self.ca_key)
        self.configs = {}
        self.identities = {}  # name -> (certificate, key)

    def check(self):
        """Every identity made so far, before anything starts: RunError naming the first bad one."""
        for name in sorted(self.identities):
            problem = identity_problem(*self.identities[name])
            if problem:
                raise RunError(f"--secure: {problem}", 2)

    def config_for(self, name, publish, partition=None):
        """Makes participant `name`'s identity and permissions (once); returns its Cyclone config path."""
        if name in self.configs:
            return self.configs[name]
        cert, key = make_identity(self.dir, name, self.ca_cert, self.ca_key)
        self.identities[name] = (cert, key)
        perms = sign(self.dir, permissions_xml(name, self.domain, publish, partition), f"{name}.permissions",
                     self.ca_cert, self.ca_key)
        path = self.dir / f"{name}.cyclonedds.xml"
        path.write_text(with_security(self.base, security_xml(self.plugins, self.ca_cert, cert, key,
                                                              self.governance, perms)))
        self.configs[name] = path
        return path

    def forged_config(self, name="agent2"):
        """A participant whose certificate and permissions (publish and subscribe everything) come
        from a CA of its own, not the run's: what an outsider can make. Its config path."""
        rogue = self.dir / "rogue"
        rogue.mkdir(exist_ok=True)
        ca_cert, ca_key = make_ca(rogue, name="rogue CA")
        cert, key = make_identity(rogue, name, ca_cert, ca_key)
        governance = sign(rogue, governance_xml(self.domain), "governance", ca_cert, ca_key)
        perms = sign(rogue, permissions_xml(name, self.domain, ["*"], partition="*"), f"{name}.permissions",
                     ca_cert, ca_key)
        path = rogue / f"{name}.cyclonedds.xml"
        path.write_text(with_security(self.base, security_xml(self.plugins, ca_cert, cert, key, governance, perms)))
        return path

    def agent_config(self, rid):
        return self.config_for(participant_name("agent", rid), AGENT_TOPICS, partition=f"robot{rid}")

    def feeder_config(self):
        return self.config_for("feeder", [(FEEDER_TOPICS, None), (FEEDER_PARTITION_TOPICS, FEEDER_PARTITION)])
