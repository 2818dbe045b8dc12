"""Least-squares rigid fits of 2-D point sets, for the scripts that score maps with numpy
(relay-error, mrclam-floor). Needs Debian's python3-numpy; the launcher's modules do not import
this one."""

import math

import numpy as np


def rigid_fit(src, dst):
    """(R, t) minimising |R src + t - dst|^2 (Umeyama, no scale)."""
    ms, md = src.mean(0), dst.mean(0)
    u, _, vt = np.linalg.svd((src - ms).T @ (dst - md))
    d = np.diag([1.0, np.sign(np.linalg.det(vt.T @ u.T))])
    r = vt.T @ d @ u.T
    return r, md - r @ ms


def rmse(errors):
    """RMSE of 2-D errors (N x 2, or a flat list of pairs); None for none."""
    e = np.asarray(errors, dtype=float).reshape(-1, 2)
    return float(math.sqrt(np.mean(np.sum(e * e, axis=1)))) if len(e) else None
