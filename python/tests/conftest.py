"""Seeded synthetic scenes written as XYZ, PLY and LAS for the binding tests.

Coordinates sit on a 1 mm grid, the grid of the bounded mode's default
tolerance (0.5 mm), so an archive gives every coordinate back exactly and the
tests compare point sets, not approximations.
"""

import os
import struct

import numpy as np
import pytest

GRID = 0.001  # metres: 2 x the default tolerance


def make_scene(n=20000, seed=7, x0=0.0, extent=40.0):
    """A rolling terrain with colour and intensity, on the 1 mm grid."""
    rng = np.random.default_rng(seed)
    x = x0 + rng.uniform(0, extent, n)
    y = rng.uniform(0, extent, n)
    z = 2.0 * np.sin(x / 6.0) + 1.5 * np.cos(y / 5.0) + rng.normal(0, 0.02, n)
    x, y, z = (np.round(v / GRID) * GRID for v in (x, y, z))
    red = ((z - z.min()) / (np.ptp(z) + 1e-9) * 255).astype(np.uint8)
    green = (255 - red).astype(np.uint8)
    blue = rng.integers(0, 256, n).astype(np.uint8)
    intensity = rng.integers(0, 1000, n).astype(np.float32)
    return {"x": x, "y": y, "z": z, "red": red, "green": green, "blue": blue, "intensity": intensity}


def write_xyz(path, s):
    """x y z r g b i per line (needs columns="x,y,z,r,g,b,i")."""
    data = np.column_stack([s["x"], s["y"], s["z"], s["red"], s["green"], s["blue"], s["intensity"]])
    np.savetxt(path, data, fmt=["%.3f", "%.3f", "%.3f", "%d", "%d", "%d", "%d"])


def write_ply(path, s):
    """Binary little-endian PLY: double x y z, uchar red green blue."""
    n = len(s["x"])
    rec = np.zeros(n, dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("red", "u1"), ("green", "u1"), ("blue", "u1")])
    for k in rec.dtype.names:
        rec[k] = s[k]
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {n}\n"
        "property double x\nproperty double y\nproperty double z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\n"
        "end_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(rec.tobytes())


LAS_SCALE = 0.001


def write_las(path, s, classification, levels_8bit=False):
    """LAS 1.2, point format 2 (XYZ, intensity, returns, class, RGB), scale 1 mm.
    Colours as 16-bit levels v * 257, or with ``levels_8bit`` as the 8-bit
    levels themselves (what many writers put in the 16-bit fields)."""
    n = len(s["x"])
    offset = (float(np.floor(s["x"].min())), float(np.floor(s["y"].min())), 0.0)
    rec = np.zeros(
        n,
        dtype=[
            ("X", "<i4"), ("Y", "<i4"), ("Z", "<i4"), ("intensity", "<u2"), ("returns", "u1"),
            ("classification", "u1"), ("scan_angle", "i1"), ("user_data", "u1"), ("point_source_id", "<u2"),
            ("R", "<u2"), ("G", "<u2"), ("B", "<u2"),
        ],
    )
    assert rec.dtype.itemsize == 26
    rec["X"] = np.round((s["x"] - offset[0]) / LAS_SCALE)
    rec["Y"] = np.round((s["y"] - offset[1]) / LAS_SCALE)
    rec["Z"] = np.round((s["z"] - offset[2]) / LAS_SCALE)
    rec["intensity"] = s["intensity"].astype(np.uint16)
    rec["returns"] = 1 | (1 << 3)  # return 1 of 1
    rec["classification"] = classification
    rec["point_source_id"] = 7
    # 8-bit colours as 16-bit LAS values (v * 257: the high byte is v), or as they are.
    scale = 1 if levels_8bit else 257
    rec["R"], rec["G"], rec["B"] = (s[c].astype(np.uint16) * scale for c in ("red", "green", "blue"))
    header_size = 227
    header = b"LASF" + struct.pack("<HH16sBB32s32sHHHIIBHI5I", 0, 0, b"\0" * 16, 1, 2, b"relief tests", b"relief tests",
                                    1, 2024, header_size, header_size, 0, 2, 26, n, n, 0, 0, 0, 0)
    header += struct.pack("<3d3d", LAS_SCALE, LAS_SCALE, LAS_SCALE, *offset)
    header += struct.pack("<6d", s["x"].max(), s["x"].min(), s["y"].max(), s["y"].min(), s["z"].max(), s["z"].min())
    assert len(header) == header_size
    with open(path, "wb") as f:
        f.write(header)
        f.write(rec.tobytes())


def as_rows(arr, names):
    """The points as a sorted int64 matrix (coordinates in grid steps), for
    comparing point sets whatever their order."""
    cols = []
    for k in names:
        v = arr[k]
        cols.append(np.round(v / GRID).astype(np.int64) if k in ("x", "y", "z") else v.astype(np.int64))
    m = np.column_stack(cols)
    return m[np.lexsort(m.T[::-1])]


@pytest.fixture(scope="session")
def scene():
    return make_scene()


@pytest.fixture(scope="session")
def xyz_archive(tmp_path_factory, scene):
    """An archive of the scene from XYZ (colour and intensity), 8 m chunks."""
    import relief

    d = tmp_path_factory.mktemp("xyz")
    src = d / "scene.xyz"
    write_xyz(src, scene)
    out = d / "scene.relief"
    result = relief.compress([src], out, columns="x,y,z,r,g,b,i", chunk_edge=8, threads=2)
    return out, result


def pytest_sessionfinish(session, exitstatus):
    """With RELIEF_PYTEST_SKIP_CODE set (ctest does), a run that passed but
    skipped a test exits with that code, so ctest shows it as skipped."""
    code = os.environ.get("RELIEF_PYTEST_SKIP_CODE")
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if code and exitstatus == 0 and reporter is not None and reporter.stats.get("skipped"):
        session.exitstatus = int(code)
