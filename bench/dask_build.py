"""The sharded Dask build (relief.distributed) against a one-box `relief compress`
of the same generated inputs: wall seconds and M points/s with 1, 2 and 3 worker
processes on this machine. Prints CSV (comment lines start with '#').

    PYTHONPATH=python RELIEF_CLI=build/tools/relief /usr/bin/python3 bench/dask_build.py \
        [--points 10000000] [--files 8] [--workers 1,2,3] [--ranges 6] [--tmp DIR]

The inputs are a seeded terrain with colour and intensity (~100 points/m^2),
written as binary PLY files (double x y z, RGB, float intensity) into --tmp and
removed afterwards. Each build runs the relief CLI (one-box: all cores;
Dask: each task --threads 1, one task per worker process, which is where the
parallelism comes from). Every Dask archive is checked to hold the one-box
archive's chunk rows. Wall time includes starting the local cluster."""

import argparse
import os
import shutil
import sqlite3
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "python"))
from relief import distributed as rd  # noqa: E402

PLY_DTYPE = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("red", "u1"), ("green", "u1"),
                      ("blue", "u1"), ("intensity", "<f4")])
# Points generated per block (memory stays ~block x 31 bytes).
BLOCK = 1 << 20


def write_inputs(directory, points, files, seed=2024):
    side = np.sqrt(points / 100.0)  # ~100 points per square metre
    rng = np.random.default_rng(seed)
    paths = []
    per_file = [points // files + (1 if k < points % files else 0) for k in range(files)]
    for k, n in enumerate(per_file):
        path = os.path.join(directory, "tile%02d.ply" % k)
        with open(path, "wb") as f:
            f.write(("ply\nformat binary_little_endian 1.0\nelement vertex %d\n"
                     "property double x\nproperty double y\nproperty double z\n"
                     "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                     "property float intensity\nend_header\n" % n).encode())
            # File k is the strip k of the square (files cover it side by side).
            done = 0
            while done < n:
                m = min(BLOCK, n - done)
                a = np.empty(m, PLY_DTYPE)
                a["x"] = rng.uniform(k * side / files, (k + 1) * side / files, m)
                a["y"] = rng.uniform(0, side, m)
                a["z"] = 5 * np.sin(a["x"] / 40) * np.cos(a["y"] / 55) + rng.normal(0, 0.02, m)
                a["red"] = (a["x"] % 256).astype(np.uint8)
                a["green"] = (a["y"] % 256).astype(np.uint8)
                a["blue"] = rng.integers(0, 256, m, dtype=np.uint8)
                a["intensity"] = rng.uniform(0, 4000, m).astype(np.float32)
                f.write(a.tobytes())
                done += m
        paths.append(path)
    return paths


def chunk_rows(path):
    db = sqlite3.connect("file:%s?mode=ro" % path, uri=True)
    try:
        return sorted(db.execute("SELECT ix, iy, iz, codec_params, blob FROM relief_chunk").fetchall())
    finally:
        db.close()


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--points", type=int, default=10_000_000)
    p.add_argument("--files", type=int, default=8)
    p.add_argument("--workers", default="1,2,3")
    p.add_argument("--ranges", type=int, default=6)
    p.add_argument("--tmp", default=None)
    args = p.parse_args()
    from distributed import Client, LocalCluster

    cli = rd.find_cli()
    tmp = tempfile.mkdtemp(prefix="relief-bench-dask-", dir=args.tmp)
    try:
        t = time.perf_counter()
        inputs = write_inputs(tmp, args.points, args.files)
        print("# %d points in %d PLY files generated in %.1f s (%s); %d cores" %
              (args.points, args.files, time.perf_counter() - t, tmp, os.cpu_count() or 0))
        print("build,workers,ranges,seconds,mpoints_per_s,chunks,same_rows_as_one_box")
        one = os.path.join(tmp, "one.relief")
        t = time.perf_counter()
        subprocess.run([cli, "compress"] + inputs + ["-o", one, "--quiet"], check=True)
        s = time.perf_counter() - t
        want = chunk_rows(one)
        print("one-box,-,-,%.2f,%.2f,%d,-" % (s, args.points / s / 1e6, len(want)), flush=True)
        for w in [int(x) for x in args.workers.split(",")]:
            out = os.path.join(tmp, "dask%d.relief" % w)
            t = time.perf_counter()
            with LocalCluster(n_workers=w, threads_per_worker=1, processes=True,
                              dashboard_address=None) as cluster, Client(cluster) as client:
                r = rd.compress(inputs, out, client=client, ranges=args.ranges)
            s = time.perf_counter() - t
            got = chunk_rows(out)
            print("dask,%d,%d,%.2f,%.2f,%d,%s" % (w, r["ranges"], s, args.points / s / 1e6, len(got),
                                                 "yes" if got == want else "NO"), flush=True)
            os.unlink(out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
