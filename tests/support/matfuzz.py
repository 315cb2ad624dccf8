"""Byte-mutated MATLAB files for the fuzz tests (tests/test_matfile.py, tests/cli/test_corrupt_mat.py):
a small THOR lidar + joint pair, saved plain and compressed, and seeded mutations of them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.io as sio

from pfslam.io.thor import write_thor

MUTATIONS = ("flip", "truncate", "insert", "delete", "header")


def thor_pair(folder: Path, n: int = 30) -> dict[str, Path]:
    """A valid THOR pair, plain and compressed: {"lidar", "joint", "lidar_z", "joint_z"}."""
    rng = np.random.default_rng(5)
    t = 1000.0 + np.arange(n) / 40.0
    scans = rng.uniform(0.5, 8.0, (n, 1081)).astype(np.float32)
    pose = np.column_stack([np.linspace(0, 0.5, n), np.zeros(n), np.linspace(0, 0.1, n)])
    jt = np.linspace(t[0] - 0.1, t[-1] + 0.1, 2 * n)
    paths = {"lidar": folder / "train_lidar0.mat", "joint": folder / "train_joint0.mat"}
    write_thor(
        paths["lidar"],
        paths["joint"],
        t=t,
        scans=scans,
        pose=pose,
        rpy=np.zeros((n, 3)),
        joint_ts=jt,
        head_angles=np.vstack([np.linspace(0, 0.3, 2 * n), np.full(2 * n, 0.1)]),
        joint_rpy=np.zeros((3, 2 * n)),
    )
    for name in ("lidar", "joint"):
        m = {k: v for k, v in sio.loadmat(paths[name]).items() if not k.startswith("__")}
        paths[name + "_z"] = folder / f"train_{name}0_z.mat"
        sio.savemat(paths[name + "_z"], m, do_compression=True)
    return paths


def mutate(data: bytes, rng: np.random.Generator, kind: str) -> bytes:
    """``data`` with one mutation of ``kind`` (one of ``MUTATIONS``)."""
    b = bytearray(data)
    if kind == "flip":  # a few random bytes anywhere
        for _ in range(int(rng.integers(1, 9))):
            b[int(rng.integers(len(b)))] = int(rng.integers(256))
    elif kind == "truncate":
        del b[int(rng.integers(len(b))) :]
    elif kind == "insert":
        i = int(rng.integers(len(b)))
        b[i:i] = rng.integers(0, 256, int(rng.integers(1, 65)), dtype=np.uint8).tobytes()
    elif kind == "delete":
        i = int(rng.integers(len(b)))
        del b[i : i + int(rng.integers(1, 65))]
    elif kind == "header":  # the 128-byte header and the first tags after it
        for _ in range(int(rng.integers(1, 4))):
            b[int(rng.integers(min(len(b), 160)))] = int(rng.integers(256))
    else:
        raise ValueError(kind)
    return bytes(b)


def mutants(paths: dict[str, Path], count: int, seed: int):
    """``count`` (which, kind, bytes) mutants, cycling over the four files and the five kinds."""
    rng = np.random.default_rng(seed)
    names = ("lidar", "joint", "lidar_z", "joint_z")
    data = {k: paths[k].read_bytes() for k in names}
    for i in range(count):
        which, kind = names[i % 4], MUTATIONS[(i // 4) % len(MUTATIONS)]
        yield which, kind, mutate(data[which], rng, kind)
