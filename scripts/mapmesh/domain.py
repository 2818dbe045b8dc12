"""Free DDS domain ids, leased with flock: the same files as common/transport/domain_lease.h,
so parallel runs and tests on this host never share a domain."""

import fcntl
import os

LOCK_DIR = "/tmp/mapmesh-domains"
FIRST, LAST = 1, 97  # Cyclone ports 7400 + 250 * id stay below the ephemeral port range


class DomainLease:
    """Holds one domain id until close() (or process exit)."""

    def __init__(self):
        os.makedirs(LOCK_DIR, exist_ok=True)
        try:
            os.chmod(LOCK_DIR, 0o777)
        except OSError:
            pass
        n = LAST - FIRST + 1
        start = os.getpid() % n
        for k in range(n):
            dom = FIRST + (start + k) % n
            fd = os.open(os.path.join(LOCK_DIR, f"{dom}.lock"), os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                continue
            self.id, self._fd = dom, fd
            return
        raise RuntimeError(f"no free DDS domain id in {LOCK_DIR}")

    def close(self):
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
