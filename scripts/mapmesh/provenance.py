"""How a run was made (DIR/run.json): the options it was started with, the scenario as resolved
(every key the loader read, with the value it took), a copy of the scenario file, the code
version, the Cyclone DDS version and the host; and the options back from a run.json, for
`swarm run --from` (docs/OUTPUTS.md "run.json"). Standard library only."""

import hashlib
import json
import os
import platform
import shutil
import subprocess
import sys
from pathlib import Path

RUN_JSON = "run.json"
SCENARIO_COPY = "scenario.yaml"
VERSION = 1
# The `swarm run` options a run is made with, as argparse names them: what --from restores.
OPTIONS = ("scenario", "agents", "kill", "restart", "pause", "set", "pace", "rate", "timeout", "inject",
           "inject_period", "inject_sim_period", "secure", "inject_identity", "hosts", "net_loss", "net_rate",
           "no_reference", "gap_samples")
REPO = Path(__file__).resolve().parents[2]


def option_flags(values, defaults):
    """The `swarm run` flags that give a run these option values (a dict or namespace of OPTIONS
    but the scenario; those at their defaults are not repeated). ValueError (one line) on a value
    no command line could give: a flag's value that is not true or false, a repeatable option's
    that is not a list of strings."""
    get = values.get if isinstance(values, dict) else lambda n, d=None: getattr(values, n, d)
    flags = []
    for name in OPTIONS:
        if name == "scenario" or name not in defaults:
            continue
        value = get(name, None)
        if value == defaults[name] or value is None:
            continue
        flag = "--" + name.replace("_", "-")
        if isinstance(defaults[name], bool):
            if not isinstance(value, bool):
                raise ValueError(f"{name}: {value!r}, expected true or false")
            flags.append(flag)
        elif isinstance(value, list):
            if not all(isinstance(v, str) for v in value):
                raise ValueError(f"{name}: {value!r}, expected a list of strings")
            for v in value:
                flags += [flag, v]
        elif isinstance(value, (bool, dict)):
            raise ValueError(f"{name}: {value!r}, expected a value")
        else:
            flags += [flag, str(value)]
    return flags


def sha256_of(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def code_version(repo=REPO):
    """{"describe", "commit", "dirty"} from git, or None outside a git work tree."""
    def git(*args):
        r = subprocess.run(["git", "-C", str(repo)] + list(args), capture_output=True, text=True)
        return r.stdout.strip() if r.returncode == 0 else None
    if shutil.which("git") is None or git("rev-parse", "--is-inside-work-tree") != "true":
        return None
    status = git("status", "--porcelain", "--untracked-files=no")
    return {"describe": git("describe", "--always", "--dirty", "--tags"), "commit": git("rev-parse", "HEAD"),
            "dirty": bool(status)}


def cyclone_version():
    """The Cyclone DDS library's Debian package version, or None."""
    r = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "libddsc0debian"], capture_output=True, text=True) \
        if shutil.which("dpkg-query") else None
    return r.stdout.strip() if r is not None and r.returncode == 0 and r.stdout.strip() else None


def host_facts():
    return {"hostname": platform.node(), "system": platform.platform(), "machine": platform.machine(),
            "cpus": os.cpu_count(), "python": platform.python_version()}


def options_of(args):
    """The run options of parsed `swarm run` arguments, JSON-ready."""
    return {name: getattr(args, name, None) for name in OPTIONS}


def write_run_json(out, args, info, kills, restarts, pauses, bin_dir):
    """Writes DIR/run.json and DIR/scenario.yaml (a copy of the scenario file) before the run starts."""
    out = Path(out)
    scenario = Path(args.scenario).resolve()
    shutil.copyfile(scenario, out / SCENARIO_COPY)
    record = {
        "version": VERSION,
        "argv": sys.argv,
        "cwd": os.getcwd(),
        "options": options_of(args),
        "scenario_file": str(scenario),
        "scenario_sha256": sha256_of(scenario),
        "scenario_copy": SCENARIO_COPY,
        "scenario_name": info.get("name"),
        "seed": info.get("seed"),
        "robots": info.get("robots"),
        "duration_s": info.get("duration"),
        "pace": args.pace or info.get("pace"),
        "faults": {"kills": [{"id": r, "t": t} for t, r in kills],
                   "restarts": [{"id": r, "t": t} for t, r in restarts],
                   "pauses": [{"id": r, "t": t, "seconds": s} for t, r, s in pauses]},
        "resolved": info.get("resolved"),
        "code": code_version(),
        "binaries": str(bin_dir),
        "cyclonedds": cyclone_version(),
        "host": host_facts(),
    }
    tmp = out / (RUN_JSON + ".tmp")
    tmp.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
    os.replace(tmp, out / RUN_JSON)
    return record


def options_from(path):
    """The run options recorded in a run.json, with the scenario file to use: the original when it
    is still there unchanged, else the copy beside the run.json. Raises ValueError (one line)."""
    from .rundir import read_json, why_unreadable
    path = Path(path)
    try:
        record = read_json(path, max_bytes=16 * 1024 * 1024)
    except (OSError, ValueError) as e:
        raise ValueError(f"--from {path}: not a readable run.json ({why_unreadable(e)})") from None
    if not isinstance(record, dict) or record.get("version") != VERSION or not isinstance(record.get("options"), dict):
        raise ValueError(f"--from {path}: not a run.json of this version (written by `swarm run`)")
    options = {k: record["options"].get(k) for k in OPTIONS}
    original = Path(str(record.get("scenario_file", "")))
    copy_name = record.get("scenario_copy", SCENARIO_COPY)
    if not isinstance(copy_name, str) or not copy_name or Path(copy_name).name != copy_name or copy_name in (".", ".."):
        raise ValueError(f"--from {path}: scenario_copy {copy_name!r} is not a file name in the run's folder")
    copy = path.parent / copy_name
    if original.is_file() and sha256_of(original) == record.get("scenario_sha256"):
        options["scenario"] = str(original)
    elif copy.is_file():
        options["scenario"] = str(copy)
    else:
        raise ValueError(f"--from {path}: neither the scenario {original} (unchanged) nor its copy {copy} is there")
    return options, record


def print_config(resolved):
    """The resolved scenario, one `key: value` line per key in path order (values as JSON)."""
    for key in sorted(resolved):
        print(f"{key}: {json.dumps(resolved[key])}")


def apply_from(args):
    """`swarm run --from DIR/run.json`: every run option of args set as that run was made (the
    scenario file unchanged, else the copy beside the run.json), through the command line's own
    parser and ranges. RunError (one line) when an option is given beside --from or the run.json
    is unusable."""
    from .run_error import RunError
    if args.scenario:
        raise RunError(f"--from {args.from_run}: the scenario comes from the run.json; give no SCENARIO", 2)
    defaults = getattr(args, "option_defaults", {})
    given = [n for n in OPTIONS if n != "scenario" and n in defaults and getattr(args, n) != defaults[n]]
    if given:
        raise RunError(f"--from {args.from_run}: every run option comes from the run.json; give none beside it "
                       f"(got --{given[0].replace('_', '-')})", 2)
    try:
        options, _ = options_from(args.from_run)
        # Every option as the command line takes it: the same parser, the same ranges.
        if hasattr(args, "options_parser"):
            parsed = args.options_parser().parse_args(option_flags(options, defaults))
            why = args.option_values_error(parsed)
            if why:
                raise ValueError(why)
            options = {name: getattr(parsed, name) if name != "scenario" else value
                       for name, value in options.items()}
    except ValueError as e:
        message = str(e)
        where = "" if message.startswith("--from") else f"--from {args.from_run}: "
        raise RunError(where + message, 2) from None
    for name, value in options.items():
        setattr(args, name, value)
