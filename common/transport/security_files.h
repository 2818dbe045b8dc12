#pragma once
// The identity files a Cyclone config's DDS Security section names (its certificate and private
// key), checked before a participant is made: with a key that does not match its certificate
// the process comes up and every handshake fails, so the run waits for it in vain; a key others
// may read is no longer private. Parsing is pure; the check reads the files (OpenSSL).

#include <optional>
#include <string>

namespace mapmesh::transport {

struct SecurityFiles {
  std::string certificate;  // <IdentityCertificate>, a path ("file:" taken off)
  std::string private_key;  // <PrivateKey>
  std::string identity_ca;  // <IdentityCA>, empty when not a file
};

// The files a config's <Security> section names; nullopt without one, or when either is not a
// file (inline "data:," values are Cyclone's to judge).
std::optional<SecurityFiles> SecurityFilesOf(const std::string& config_xml);

// What is wrong with them, as one line naming the files ("KEY: ..."), or nullopt: the key is
// readable by its owner only (mode 0600 or stricter), both parse as PEM, and the key is the
// certificate's.
std::optional<std::string> CheckSecurityFiles(const SecurityFiles& files);

}  // namespace mapmesh::transport
