"""TUM trajectory files (the format of the TUM RGB-D benchmark, read by evo): one pose per line,
`timestamp tx ty tz qx qy qz qw`, space-separated, '#' lines are comments. A planar pose
(x, y, theta) is written with z = 0 and the rotation about z as a unit quaternion. Standard
library only."""

import math
import os
from pathlib import Path


def quaternion_of_yaw(theta):
    """(qx, qy, qz, qw) of a rotation by theta about z."""
    return 0.0, 0.0, math.sin(theta / 2.0), math.cos(theta / 2.0)


def compose(a, b):
    """The planar pose a * b (b expressed in a's frame, then both in a's parent)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return [a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]]


def inverse(a):
    c, s = math.cos(a[2]), math.sin(a[2])
    return [-(c * a[0] + s * a[1]), s * a[0] - c * a[1], -a[2]]


def line(t, x, y, theta):
    qx, qy, qz, qw = quaternion_of_yaw(theta)
    return f"{t:.6f} {x:.9f} {y:.9f} 0 {qx:.9f} {qy:.9f} {qz:.9f} {qw:.9f}"


def finite_pose(p):
    """Whether p is [t, x, y, theta, ...]: at least 4 finite numbers."""
    return (isinstance(p, (list, tuple)) and len(p) >= 4
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in p[:4]))


def write(path, poses, comments=()):
    """Writes [[t, x, y, theta], ...] (time order; a pose whose stamp is not after the one before
    it is left out, as TUM readers need increasing stamps) to path. Returns the poses written.
    ValueError naming the pose when one is not 4 finite numbers; nothing is left at path then
    (the file is written beside it and renamed when whole)."""
    path = Path(path)
    part = path.with_name(path.name + ".part")
    written, last = 0, None
    try:
        with open(part, "w") as f:
            for c in comments:
                f.write(f"# {c}\n")
            f.write("# timestamp tx ty tz qx qy qz qw\n")
            for i, p in enumerate(poses):
                if not finite_pose(p):
                    raise ValueError(f"pose {i}: not 4 finite numbers [t, x, y, theta]")
                t, x, y, theta = p[:4]
                if last is not None and t <= last:
                    continue
                f.write(line(t, x, y, theta) + "\n")
                written, last = written + 1, t
        os.replace(part, path)
    finally:
        part.unlink(missing_ok=True)
    return written


def read(path):
    """[[t, x, y, z, qx, qy, qz, qw], ...] of a TUM file; ValueError naming the line on a line that
    is not 8 numbers, a stamp not after the one before it, or a quaternion not of unit length."""
    out = []
    with open(path) as f:
        for n, text in enumerate(f, 1):
            text = text.strip()
            if not text or text.startswith("#"):
                continue
            fields = text.split()
            if len(fields) != 8:
                raise ValueError(f"{path}:{n}: {len(fields)} fields, expected 8")
            try:
                values = [float(v) for v in fields]
            except ValueError:
                raise ValueError(f"{path}:{n}: not a number") from None
            if not all(math.isfinite(v) for v in values):
                raise ValueError(f"{path}:{n}: not finite")
            if out and values[0] <= out[-1][0]:
                raise ValueError(f"{path}:{n}: stamp {values[0]} not after {out[-1][0]}")
            if abs(math.hypot(*values[4:8]) - 1.0) > 1e-6:
                raise ValueError(f"{path}:{n}: quaternion not of unit length")
            out.append(values)
    return out
