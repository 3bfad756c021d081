#!/usr/bin/env python3
"""Writes the seed inputs of the fuzz corpora (tests/fuzz/README.md).

Usage: tests/fuzz/make_seeds.py BUILD_DIR OUT_DIR
(RELIEF_SHARED_DATA overrides ../shared/data.) BUILD_DIR holds a built `relief` CLI (encode-chunk and compress make the chunk
and archive seeds); OUT_DIR/<target>/ receives the files. Real data comes from
tests/data and, when present, ../shared/data. The committed corpora are these
seeds plus what the fuzzers found, minimised with -merge=1.
"""
import math
import os
import sqlite3
import struct
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SHARED = os.environ.get("RELIEF_SHARED_DATA", os.path.join(os.path.dirname(ROOT), "shared", "data"))
KINECT = os.path.join(ROOT, "tests", "data", "kinect_milk_scene_rgb.ply")


def put(out, target, name, data):
    d = os.path.join(out, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def kinect_points(n, stride):
    """The first n points (every stride-th) of the Kinect scene: (x, y, z, r, g, b)."""
    with open(KINECT, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    rec = struct.Struct("<fffBBB")
    pts = []
    for i in range(0, n * stride, stride):
        pts.append(rec.unpack_from(data, end + i * rec.size))
    return pts


def ply(pts, encoding, colors=True, extra=b""):
    head = b"ply\nformat %s 1.0\n" % encoding.encode()
    head += extra
    head += b"element vertex %d\nproperty float x\nproperty float y\nproperty float z\n" % len(pts)
    if colors:
        head += b"property uchar red\nproperty uchar green\nproperty uchar blue\n"
    head += b"end_header\n"
    body = b""
    for p in pts:
        if encoding == "ascii":
            body += (" ".join("%g" % v for v in (p if colors else p[:3])) + "\n").encode()
        else:
            e = "<" if encoding == "binary_little_endian" else ">"
            body += struct.pack(e + ("fffBBB" if colors else "fff"), *(p if colors else p[:3]))
    return head + body


def ply_seeds(out, pts):
    put(out, "ply", "le_rgb.ply", ply(pts[:20], "binary_little_endian"))
    put(out, "ply", "be_xyz.ply", ply(pts[:20], "binary_big_endian", colors=False))
    put(out, "ply", "ascii_rgb.ply", ply(pts[:12], "ascii"))
    faces = b"element face 1\nproperty list uchar int vertex_indices\n"
    body = ply(pts[:3], "ascii", colors=False)
    body = body.replace(b"end_header\n", faces + b"end_header\n") + b"3 0 1 2\n"
    put(out, "ply", "ascii_face.ply", body)
    head = (b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty double x\n"
            b"property double y\nproperty double z\nproperty ushort red\nproperty ushort green\n"
            b"property ushort blue\nproperty float intensity\nend_header\n")
    body = b"".join(struct.pack("<dddHHHf", p[0], p[1], p[2], p[3] * 257, p[4] * 257, p[5] * 257, i)
                    for i, p in enumerate(pts[:4]))
    put(out, "ply", "le_double_rgb16_i.ply", head + body)


def xyz_seeds(out, pts):
    # First byte: column layout index (fuzz_xyz.cpp kColumns).
    lines = "".join("%g %g %g\n" % p[:3] for p in pts[:10]).encode()
    put(out, "xyz", "plain.xyz", b"\x00" + lines)
    csv = "x,y,z,r,g,b\n" + "".join("%g,%g,%g,%d,%d,%d\n" % p for p in pts[:10])
    put(out, "xyz", "rgb.csv", b"\x01" + csv.encode())
    txt = "# comment\n// other comment\n" + "".join("%g\t%g\t%g\t%d\n" % (p[0], p[1], p[2], i)
                                                    for i, p in enumerate(pts[:8]))
    put(out, "xyz", "intensity_tabs.txt", b"\x02" + txt.encode())
    semi = "".join("%d;%g;%d;%g;%g\n" % (i, p[0], i, p[1], p[2]) for i, p in enumerate(pts[:6]))
    put(out, "xyz", "skip_semicolon.xyz", b"\x04" + semi.encode())
    typed = "".join("%g %g %g %d %g\n" % (p[0], p[1], p[2], 40000 + i, p[3] / 7.0) for i, p in enumerate(pts[:6]))
    put(out, "xyz", "typed_u16_f32.xyz", b"\x08" + typed.encode())
    typed = "".join("%g,%g,%g,%d,skip,%.17g,%d,%d\n" % (p[0], p[1], p[2], -(1 << 62) + i, p[4] / 3.0, p[5], i - 3)
                    for i, p in enumerate(pts[:6]))
    put(out, "xyz", "typed_i64_f64_u8_i8.csv", b"\x09" + typed.encode())
    put(out, "xyz", "rgbi_crlf.xyz",
        b"\x03" + "".join("%g %g %g %d %d %d 0.5\r\n" % p for p in pts[:6]).encode())


def stream_seed(binary, spec, body):
    # fuzz_stream.cpp: byte 0 picks the parser (odd: binary), byte 1 the spec's length.
    spec = spec.encode()
    return bytes([1 if binary else 0, len(spec)]) + spec + body


def stream_seeds(out, pts):
    put(out, "stream", "text_rgbi.txt", stream_seed(False, "x,y,z,r,g,b,i",
        "".join("%g %g %g %d %d %d %d\n" % (p + (i * 37,)) for i, p in enumerate(pts[:8])).encode()))
    put(out, "stream", "text_las.txt", stream_seed(False, "x,y,z,classification,return_number,number_of_returns,"
        "gps_time,scan_angle,point_source_id", "".join("%g,%g,%g,%d,%d,2,%.6f,%d,%d\n" % (
            p[0], p[1], p[2], 2 + i % 4, 1 + i % 2, 1000.5 + i * 1e-5, i - 3, 7) for i, p in enumerate(pts[:8])).encode()))
    put(out, "stream", "text_typed.txt", stream_seed(False, "x,y,z,amplitude:f32,ring:u16,id:i64", "".join(
        "%g %g %g %g %d %d\n" % (p[0], p[1], p[2], p[3] / 9.0, 60000 + i, -(1 << 60) - i) for i, p in enumerate(pts[:8])).encode()))
    put(out, "stream", "text_skip.txt", stream_seed(False, "_,z,_,y,x", b"1 2 3 4 5\n6;7;8;9;10\n\nbad\n"))
    rec = b"".join(struct.pack("<dddBBBf", p[0], p[1], p[2], p[3], p[4], p[5], i * 0.5) for i, p in enumerate(pts[:8]))
    put(out, "stream", "binary_rgbi.bin", stream_seed(True, "rgb,intensity", rec))
    rec = b"".join(struct.pack("<dddd B B xx f H", p[0], p[1], p[2], 5e5 + i * 1e-4, 2, 1 + i % 3, 0.25 * i, i)
                   for i, p in enumerate(pts[:8]))
    put(out, "stream", "binary_las_extra.bin", stream_seed(True, "gps_time,classification,return_number,_2,"
                                                           "amplitude:f32,ring:u16", rec))
    rec = b"".join(struct.pack("<ddd f H B", p[0], p[1], p[2], 12.5 - i, 300 + i, i % 2) for i, p in enumerate(pts[:8]))
    put(out, "stream", "binary_angle_nir.bin", stream_seed(True, "scan_angle,nir,synthetic", rec))


def pcd(pts, data_kind):
    head = ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\n"
            "TYPE F F F U\nCOUNT 1 1 1 1\nWIDTH %d\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\n"
            "DATA %s\n" % (len(pts), len(pts), data_kind)).encode()
    if data_kind == "ascii":
        body = "".join("%g %g %g %d\n" % (p[0], p[1], p[2], (p[3] << 16) | (p[4] << 8) | p[5])
                       for p in pts).encode()
    elif data_kind == "binary":
        body = b"".join(struct.pack("<fffI", p[0], p[1], p[2], (p[3] << 16) | (p[4] << 8) | p[5]) for p in pts)
    else:  # binary_compressed is not produced; a header that names it is still a seed
        body = b""
    return head + body


def pcd_seeds(out, pts):
    put(out, "pcd", "ascii_rgb.pcd", pcd(pts[:10], "ascii"))
    put(out, "pcd", "binary_rgb.pcd", pcd(pts[:10], "binary"))
    put(out, "pcd", "binary_compressed.pcd", pcd(pts[:4], "binary_compressed"))
    organised = ("VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
                 "WIDTH 2\nHEIGHT 2\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA ascii\n"
                 "1 2 3 0.5\nnan nan nan 0\n4 5 6 1\n7 8 9 2\n").encode()
    put(out, "pcd", "organised_nan_intensity.pcd", organised)


def las_cut(data, keep):
    """The header, VLRs and the first `keep` point records of a LAS file, counts fixed."""
    header_size = struct.unpack_from("<H", data, 94)[0]
    offset = struct.unpack_from("<I", data, 96)[0]
    record_len = struct.unpack_from("<H", data, 105)[0]
    legacy_count = struct.unpack_from("<I", data, 107)[0]
    minor = data[25]
    total = legacy_count
    if minor >= 4 and header_size >= 255:
        total = struct.unpack_from("<Q", data, 247)[0]
    keep = min(keep, total)
    out = bytearray(data[:offset + keep * record_len])
    struct.pack_into("<I", out, 107, keep if legacy_count else 0)
    struct.pack_into("<5I", out, 111, keep, 0, 0, 0, 0)
    if minor >= 4 and header_size >= 255:
        struct.pack_into("<Q", out, 247, keep)
        struct.pack_into("<15Q", out, 255, *([keep] + [0] * 14))
        # Extended VLRs after the points would now be past the end: drop them.
        struct.pack_into("<QI", out, 235, 0, 0)
    return bytes(out)


def las_seeds(out):
    names = ["las-crs/autzen-thin-srs.las", "las-crs/interesting.las", "las-crs/lots_of_vlr.las",
             "las-crs/mvk-thin.las", "laz/simple.las", "laz/1.2-with-color.copc.las",
             "laz/laszip-generated_with2bytespadding.las"]
    for name in names:
        path = os.path.join(SHARED, name)
        if not os.path.exists(path):
            print("make_seeds: skipping absent", path)
            continue
        with open(path, "rb") as f:
            data = f.read()
        put(out, "las", os.path.basename(name), las_cut(data, 16))


def self_contained(arc):
    """Folds the WAL back in and packs the archive into 512-byte pages, so the
    seed is one small file; returns the first three chunk blobs."""
    con = sqlite3.connect(arc)
    con.execute("PRAGMA journal_mode = DELETE")
    con.execute("PRAGMA page_size = 512")
    con.execute("VACUUM")
    blobs = con.execute("SELECT blob FROM relief_chunk ORDER BY id LIMIT 3").fetchall()
    con.close()
    return blobs


def pyramid_seeds(out, relief, tmp):
    """An error-bounded archive with a level-of-detail pyramid (format-spec/archive.md
    §9) of a synthetic 12 x 12 terrain with intensity and classification, and the same
    archive with its pyramid record removed (rows no reader uses, as a run killed while
    building its pyramid leaves them). About 21 kB each, under the archive target's
    max_len (32768): SQLite's schema alone takes most of it."""
    src = os.path.join(tmp, "terrain.xyz")
    with open(src, "w") as f:
        for i in range(12):
            for j in range(12):
                x, y = 0.35 * i, 0.35 * j
                z = math.sin(0.5 * x) + math.cos(0.4 * y)
                f.write("%g %g %g %d %d\n" % (x, y, z, (7 * i + 3 * j) % 250, 2 if z < 1.2 else 5))
    arc = os.path.join(tmp, "pyramid.relief")
    subprocess.run([relief, "compress", src, "-o", arc, "--quiet", "--threads", "1", "--columns", "x,y,z,i,c",
                    "--chunk-edge", "2", "--resolution", "8", "--pyramid", "on"], check=True)
    self_contained(arc)
    con = sqlite3.connect(arc)
    if con.execute("SELECT COUNT(*) FROM relief_level_scan").fetchone()[0] == 0:
        sys.exit("make_seeds: the pyramid seed has no pyramid")
    con.close()
    with open(arc, "rb") as f:
        data = f.read()
    put(out, "archive", "seed_pyramid.relief", data)
    # The fuzz target picks its entry path by the input's size modulo 3
    # (fuzz_archive.cpp): bytes past the last page, which SQLite ignores, make
    # a copy that takes the ArchiveReader::query path (size % 3 == 1).
    put(out, "archive", "seed_pyramid_query.relief", data + bytes((1 - len(data) % 3) % 3))
    con = sqlite3.connect(arc)
    con.execute("DELETE FROM relief_level_scan")
    con.commit()
    con.execute("VACUUM")
    con.close()
    with open(arc, "rb") as f:
        put(out, "archive", "seed_pyramid_unfinished.relief", f.read())


def chunk_and_archive_seeds(out, build, pts):
    relief = os.path.join(build, "tools", "relief")
    variants = {
        "voxel_jpeg_r8": ["--resolution", "8"],
        "voxel_jpeg_r16_q30": ["--quality", "30", "--color-quality", "20"],
        "octree_jpeg": ["--decomposition", "octree", "--max-points", "64"],
        "voxel_j2k": ["--codec", "jpeg2000"],
        "octree_j2k16": ["--decomposition", "octree", "--max-points", "64", "--codec", "jpeg2000",
                         "--height-bits", "16"],
        "voxel_jpeg_r32": ["--resolution", "32"],
    }
    with tempfile.TemporaryDirectory() as tmp:
        src = os.path.join(tmp, "in.ply")
        with open(src, "wb") as f:
            f.write(ply(pts[:300], "binary_little_endian"))
        xyz_i = os.path.join(tmp, "in_i.xyz")
        with open(xyz_i, "w") as f:
            f.write("".join("%g %g %g %d\n" % (p[0], p[1], p[2], i % 200) for i, p in enumerate(pts[:300])))
        for name, opts in variants.items():
            blob = os.path.join(tmp, name + ".rlfc")
            subprocess.run([relief, "encode-chunk", src, "-o", blob, "--quiet"] + opts, check=True)
            with open(blob, "rb") as f:
                put(out, "chunk", name + ".rlfc", f.read())
        for name, inputs, opts in [("rgb", [src], ["--chunk-edge", "1"]),
                                   ("intensity_octree", [xyz_i],
                                    ["--columns", "x,y,z,i", "--decomposition", "octree", "--chunk-edge", "2"])]:
            arc = os.path.join(tmp, name + ".relief")
            subprocess.run([relief, "compress"] + inputs + ["-o", arc, "--quiet", "--threads", "1"] + opts,
                           check=True)
            blobs = self_contained(arc)
            with open(arc, "rb") as f:
                put(out, "archive", name + ".relief", f.read())
            for i, (b,) in enumerate(blobs):
                put(out, "chunk", "%s_%d.rlfc" % (name, i), bytes(b))
        pyramid_seeds(out, relief, tmp)
    for name in os.listdir(os.path.join(ROOT, "format-spec", "vectors")):
        if name.endswith(".rlfc"):
            with open(os.path.join(ROOT, "format-spec", "vectors", name), "rb") as f:
                put(out, "chunk", name, f.read())


def polygon_seeds(out):
    # fuzz_polygon.cpp: WKT text as `query --polygon` takes it.
    put(out, "polygon", "square.wkt", b"POLYGON ((0 0, 10 0, 10 10, 0 10, 0 0))")
    put(out, "polygon", "hole_z.wkt", b"POLYGON Z ((0 0 1, 10 0 1, 10 10 1, 0 10 1, 0 0 1), (4 4 0, 6 4 0, 6 6 0, 4 4 0))")
    put(out, "polygon", "multi.wkt",
        b"MULTIPOLYGON (((0 0, 1 0, 1 1, 0 0)), ((5 5, 9 5, 9 9, 5 9, 5 5), (6 6, 7 6, 7 7, 6 6)))")
    star = ", ".join(f"{500000 + 100 * (1 + 0.3 * math.sin(7 * a)) * math.cos(a):.3f} "
                     f"{4000000 + 100 * (1 + 0.3 * math.sin(7 * a)) * math.sin(a):.3f}"
                     for a in (2 * math.pi * i / 97 for i in range(97)))
    put(out, "polygon", "star_utm.wkt", f"polygon(({star}))".encode())
    put(out, "polygon", "comb.wkt", ("POLYGON ((" + ", ".join(
        f"{2 * i} 0, {2 * i} 1000, {2 * i + 1} 1000, {2 * i + 1} 0.5" for i in range(40)) + ", 80 -1, 0 -1))").encode())
    put(out, "polygon", "zm_exp.wkt", b"POLYGON ZM ((1e3 -2E-1 0 0, +5e3 0 0 0, 2.5e3 4e3 1 1))")
    put(out, "polygon", "bad_ring.wkt", b"POLYGON ((0 0, 1 1, 0 0))")
    # ESRI shapefiles (.shp): a square with a hole and a triangle, type 5 and
    # (with Z values) type 15, a null shape between them.
    def shp(shape_type, rings_per_record):
        records = b""
        for number, rings in enumerate(rings_per_record, 1):
            if rings is None:
                content = struct.pack("<i", 0)
            else:
                points = [p for r in rings for p in r + r[:1]]
                starts, k = [], 0
                for r in rings:
                    starts.append(k)
                    k += len(r) + 1
                content = struct.pack("<i4dii", shape_type, 0, 0, 0, 0, len(rings), len(points))
                content += struct.pack(f"<{len(starts)}i", *starts)
                content += b"".join(struct.pack("<2d", *p) for p in points)
                if shape_type in (15, 25):
                    content += struct.pack(f"<{2 + len(points)}d", *([1.0] * (2 + len(points))))
            records += struct.pack(">2i", number, len(content) // 2) + content
        header = struct.pack(">7i", 9994, 0, 0, 0, 0, 0, (100 + len(records)) // 2)
        header += struct.pack("<2i8d", 1000, shape_type, 0, 0, 0, 0, 0, 0, 0, 0)
        return header + records
    square = [(0, 0), (0, 10), (10, 10), (10, 0)]
    hole = [(4, 4), (6, 4), (6, 6), (4, 6)]
    triangle = [(20, 0), (30, 0), (25, 8)]
    put(out, "polygon", "holed.shp", shp(5, [[square, hole], None, [triangle]]))
    put(out, "polygon", "z.shp", shp(15, [[square], [triangle]]))


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    build, out = sys.argv[1], sys.argv[2]
    pts = kinect_points(300, 701)
    ply_seeds(out, pts)
    xyz_seeds(out, pts)
    stream_seeds(out, pts)
    pcd_seeds(out, pts)
    las_seeds(out)
    polygon_seeds(out)
    chunk_and_archive_seeds(out, build, pts)


if __name__ == "__main__":
    main()
