"""relief.distributed on a LocalCluster of 3 worker processes: the merged
archive holds the same chunk rows, blob for blob, and the same metadata as a
one-box ``relief compress``, also when a worker is killed mid-build.

Run: PYTHONPATH=python RELIEF_CLI=build/tools/relief /usr/bin/python3 -m pytest python/tests
(ctest runs it through run_distributed_tests.py, which reports a missing
dask/distributed as a skip.)"""

import os
import sqlite3
import struct
import subprocess

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

import relief  # noqa: E402  (python/ on PYTHONPATH)
from relief import distributed as rd  # noqa: E402

PLY_DTYPE = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("red", "u1"), ("green", "u1"),
                      ("blue", "u1"), ("intensity", "<f4")])


def write_scene(directory, seed, points, files):
    """A seeded terrain with colour and intensity, dealt round-robin into
    `files` binary PLY files."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0, 60, points)
    y = rng.uniform(0, 40, points)
    z = 2.0 * np.sin(x / 5.0) * np.cos(y / 7.0) + rng.normal(0, 0.01, points)
    cloud = np.empty(points, PLY_DTYPE)
    cloud["x"], cloud["y"], cloud["z"] = x, y, z
    cloud["red"] = (x * 4).astype(np.uint8)
    cloud["green"] = (y * 6).astype(np.uint8)
    cloud["blue"] = rng.integers(0, 256, points, dtype=np.uint8)
    cloud["intensity"] = rng.uniform(0, 4000, points).astype(np.float32)
    paths = []
    for k in range(files):
        part = cloud[k::files]
        path = os.path.join(directory, "in%d.ply" % k)
        with open(path, "wb") as f:
            f.write(("ply\nformat binary_little_endian 1.0\nelement vertex %d\n"
                     "property double x\nproperty double y\nproperty double z\n"
                     "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                     "property float intensity\nend_header\n" % len(part)).encode())
            f.write(part.tobytes())
        paths.append(path)
    return paths


LAS3_EXTRA_DTYPE = np.dtype([("X", "<i4"), ("Y", "<i4"), ("Z", "<i4"), ("intensity", "<u2"), ("returns", "u1"),
                             ("classification", "u1"), ("scan_angle", "i1"), ("user_data", "u1"),
                             ("point_source_id", "<u2"), ("gps_time", "<f8"), ("red", "<u2"), ("green", "<u2"),
                             ("blue", "<u2"), ("extra", "u1", (3,))])


def write_las(path, seed, points):
    """A LAS 1.2 point format 3 file (GPS time, 16-bit RGB) of a seeded terrain
    with every LAS field random and 3 extra bytes per point, described by an
    Extra Bytes VLR (one descriptor of 3 undocumented bytes)."""
    rng = np.random.default_rng(seed)
    scale = 0.001
    offset = (500000.0, 4000000.0, 0.0)
    x = rng.uniform(0, 60, points)
    y = rng.uniform(0, 40, points)
    z = 2.0 * np.sin(x / 5.0) * np.cos(y / 7.0) + 5.0
    rec = np.zeros(points, LAS3_EXTRA_DTYPE)
    rec["X"] = np.round(x / scale)
    rec["Y"] = np.round(y / scale)
    rec["Z"] = np.round(z / scale)
    rec["intensity"] = rng.integers(0, 65536, points)
    rec["returns"] = rng.integers(0, 256, points)
    rec["classification"] = rng.integers(0, 256, points)
    rec["scan_angle"] = rng.integers(-90, 91, points)
    rec["user_data"] = rng.integers(0, 256, points)
    rec["point_source_id"] = rng.integers(0, 65536, points)
    rec["gps_time"] = 1e8 + rng.integers(0, 1 << 30, points) * 1e-6
    for c in ("red", "green", "blue"):
        rec[c] = rng.integers(0, 65536, points)
    rec["extra"] = rng.integers(0, 256, (points, 3))
    descriptor = bytearray(192)
    descriptor[2] = 0  # undocumented bytes ...
    descriptor[3] = 3  # ... three of them
    descriptor[4:4 + 6] = b"opaque"
    vlr = struct.pack("<H16sHH32s", 0, b"LASF_Spec", 4, len(descriptor), b"") + bytes(descriptor)
    header_size = 227
    lo = [rec[a].min() * scale + o for a, o in zip("XYZ", offset)]
    hi = [rec[a].max() * scale + o for a, o in zip("XYZ", offset)]
    header = struct.pack("<4sHH16sBB32s32sHHHIIBHI5I3d3d6d", b"LASF", 0, 0, b"", 1, 2, b"", b"test", 1, 2026,
                         header_size, header_size + len(vlr), 1, 3, LAS3_EXTRA_DTYPE.itemsize, points,
                         points, 0, 0, 0, 0, scale, scale, scale, *offset,
                         hi[0], lo[0], hi[1], lo[1], hi[2], lo[2])
    assert len(header) == header_size
    with open(path, "wb") as f:
        f.write(header + vlr + rec.tobytes())
    return path


def archive_content(path):
    """Chunk rows (key, bounds, counts, codec, parameters, CRC, blob) as a sorted
    list, and the metadata that does not name a time."""
    db = sqlite3.connect("file:%s?mode=ro" % path, uri=True)
    try:
        rows = sorted(db.execute(
            "SELECT ix, iy, iz, min_x, min_y, min_z, max_x, max_y, max_z, input_points, "
            "decoded_points, codec, codec_params, crc32, blob FROM relief_chunk").fetchall())
        meta = dict(db.execute("SELECT key, value FROM relief_meta "
                               "WHERE key NOT IN ('created_at', 'meta_crc32')").fetchall())
        sources = db.execute("SELECT path, format, point_count, crs FROM relief_source ORDER BY id").fetchall()
        scans = db.execute("SELECT complete, has_rgb, has_intensity, crs FROM relief_scan").fetchall()
    finally:
        db.close()
    return rows, meta, sources, scans


OPTIONS = {"chunk_edge": 8, "tolerance": 0.002}


@pytest.fixture(scope="module")
def cluster():
    # Workers are fresh processes: they import relief.distributed from PYTHONPATH.
    with distributed.LocalCluster(n_workers=3, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as c, distributed.Client(c) as client:
        yield client


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("scene")
    inputs = write_scene(str(d), seed=1234, points=240000, files=5)
    one = os.path.join(str(d), "one.relief")
    subprocess.run([rd.find_cli(), "compress"] + inputs + ["-o", one, "--quiet"] + rd.plan_options(OPTIONS),
                   check=True)
    return inputs, one


def test_same_archive_as_one_box(cluster, scene, tmp_path):
    inputs, one = scene
    out = str(tmp_path / "dask.relief")
    result = rd.compress(inputs, out, client=cluster, ranges=4, **OPTIONS)
    assert result["ranges"] == 4
    want = archive_content(one)
    assert len(want[0]) >= 12
    assert archive_content(out) == want
    assert not os.path.exists(out + ".work")  # the work files are gone
    with pytest.raises(FileExistsError):
        rd.compress(inputs, out, client=cluster, ranges=4, **OPTIONS)
    # Their directory (the plan lists its point files by name: in0.ply ...).
    by_dir = str(tmp_path / "dir.relief")
    rd.compress(os.path.dirname(inputs[0]), by_dir, client=cluster, ranges=4, **OPTIONS)
    assert archive_content(by_dir) == want


def test_pyramid_goes_to_the_merge(cluster, scene, tmp_path):
    # shard-plan refuses --pyramid (the plan dropped it, and the merge built
    # no pyramid below 10 M points): the driver gives it to the merge.
    inputs, _ = scene
    one = str(tmp_path / "one.relief")
    subprocess.run([rd.find_cli(), "compress"] + inputs + ["-o", one, "--quiet", "--pyramid", "on"] +
                   rd.plan_options(OPTIONS), check=True)
    out = str(tmp_path / "dask.relief")
    rd.compress(inputs, out, client=cluster, ranges=4, pyramid="on", **OPTIONS)
    assert archive_content(out) == archive_content(one)
    with relief.open(out) as a, relief.open(one) as b:
        levels = a.info["scans"][0]["pyramid"]
        assert levels and levels == b.info["scans"][0]["pyramid"]


def test_worker_killed_mid_build(cluster, scene, tmp_path):
    inputs, one = scene
    markers = tmp_path / "markers"
    markers.mkdir()
    out = str(tmp_path / "dask.relief")
    # Partition task 2 and encode task 1 each kill their worker process once,
    # after writing their files and before Dask hears of it: the scheduler
    # runs them (and whatever the dead worker held) again elsewhere.
    kill = (str(markers), [("partition", 2), ("encode", 1)])
    rd.compress(inputs, out, client=cluster, ranges=4, _test_kill_once=kill, **OPTIONS)
    assert sorted(os.listdir(markers)) == ["killed-encode-1", "killed-partition-2"]
    assert archive_content(out) == archive_content(one)


def test_las_same_archive_as_one_box(cluster, tmp_path):
    # LAS inputs with every LAS field and extra bytes: the sharded build keeps
    # them all, so the archive (blobs and relief_meta's las_* keys) is the
    # one-box one.
    inputs = [write_las(str(tmp_path / ("in%d.las" % k)), 50 + k, 40000) for k in range(3)]
    one = str(tmp_path / "one.relief")
    subprocess.run([rd.find_cli(), "compress"] + inputs + ["-o", one, "--quiet"] + rd.plan_options(OPTIONS),
                   check=True)
    want = archive_content(one)
    assert "extra_bytes" in want[1]["las_attributes"]
    assert "gps_time" in want[1]["las_attributes"]
    assert len(want[0]) >= 12
    out = str(tmp_path / "dask.relief")
    # The stage-2 budget is passed on (the C++ tests cover a range larger than it).
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    result = rd.compress(inputs, out, client=cluster, ranges=3, memory_per_task="64M",
                         tmp_per_task=str(scratch), **OPTIONS)
    assert result["ranges"] == 3
    assert archive_content(out) == want
    assert os.listdir(str(scratch)) == []


def test_failed_stage_names_the_problem(cluster, tmp_path):
    bad = tmp_path / "bad.ply"
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 1000\n"
                    b"property double x\nproperty double y\nproperty double z\nend_header\n" + b"\0" * 24)
    with pytest.raises(rd.ReliefCliError) as e:
        rd.compress([str(bad)], str(tmp_path / "out.relief"), client=cluster)
    assert e.value.exit_code >= 10
    assert "bad.ply" in str(e.value)
    assert not os.path.exists(tmp_path / "out.relief")
