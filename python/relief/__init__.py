"""Relief from Python: compress point clouds into one archive file and query
boxes of it as numpy structured arrays.

    import relief
    relief.compress(["scan.las"], "scan.relief", tolerance=0.005)
    with relief.open("scan.relief") as archive:
        print(archive.info["points_in"])
        points = archive.query((0, 0, 100, 100))      # every height
        print(points["x"].mean(), points.dtype.names)

Options keep the CLI's names and meanings (``relief compress --help``), with
``_`` for ``-``: ``color_tolerance=3`` is ``--color-tolerance 3``. The same
library code checks them for both. Every failure the library reports raises
:class:`Error` (a subclass per stable code) carrying ``.code`` and
``.code_name``.
"""

import builtins as _builtins
import json as _json
import operator as _operator
import os as _os
import socket as _socket
import warnings as _warnings

from . import _relief

__all__ = [
    "Archive",
    "CorruptDataError",
    "Error",
    "FormatError",
    "InternalError",
    "InvalidArgumentError",
    "IoError",
    "LimitExceededError",
    "UnsupportedError",
    "append",
    "check",
    "compress",
    "open",
    "read",
    "retain_freed_memory",
    "write",
]

__version__ = _relief.__version__


class Error(Exception):
    """A failure reported by the Relief library.

    ``code`` is the stable numeric code (relief/status.h; the CLI exits with
    10 + code), ``code_name`` its short name (e.g. ``"corrupt-data"``) and the
    message the library's, naming the file and the problem.
    """

    code = None
    code_name = None

    def __init__(self, message, code=None, code_name=None):
        super().__init__(message)
        if code is not None:
            self.code = code
        if code_name is not None:
            self.code_name = code_name


class InvalidArgumentError(Error, ValueError):
    """Parameters that cannot work (code 1): a bad option value or box."""


class IoError(Error, OSError):
    """A file could not be opened, read or written (code 2)."""


class FormatError(Error):
    """An input file or archive is malformed (code 3)."""


class CorruptDataError(Error):
    """A compressed chunk failed validation or its checksum (code 4)."""


class UnsupportedError(Error):
    """Well-formed, but a feature or version this build lacks (code 5)."""


class LimitExceededError(Error):
    """A safety limit on sizes was hit (code 6)."""


class InternalError(Error):
    """A dependency failed in a way the inputs do not explain (code 7)."""


_ERRORS_BY_CODE = {
    1: InvalidArgumentError,
    2: IoError,
    3: FormatError,
    4: CorruptDataError,
    5: UnsupportedError,
    6: LimitExceededError,
    7: InternalError,
}


def _make_error(code, code_name, message):
    # OSError's constructor reads (errno, strerror) from two arguments: give
    # every class the message alone, then the code.
    error = _ERRORS_BY_CODE.get(code, Error)(message)
    error.code = code
    error.code_name = code_name
    return error


_relief._set_error_factory(_make_error)


def _invalid(message):
    """InvalidArgumentError with its code, for the checks made here."""
    return _make_error(1, "invalid-argument", message)


def _whole(value, what, lo, hi):
    """A whole-number argument within [lo, hi] (numpy integers too), else
    InvalidArgumentError naming it: the C++ side would raise a bare TypeError
    for a negative or too large value."""
    try:
        v = None if isinstance(value, bool) else _operator.index(value)
    except TypeError:
        v = None
    if v is None or not lo <= v <= hi:
        raise _invalid(f"{what} must be a whole number from {lo} to {hi}, got {value!r}")
    return v


def _path(value, what):
    """A path argument (str, bytes or os.PathLike) as text, or as bytes when its name is not
    UTF-8 (a file name os.listdir gives with surrogate escapes: the library takes the bytes);
    anything else is a TypeError (None made a file named 'None'), a NUL inside an
    InvalidArgumentError (the name would end there)."""
    if not isinstance(value, (str, bytes, _os.PathLike)):
        raise TypeError(f"{what} must be a path (str, bytes or os.PathLike), got {type(value).__name__}")
    text = _os.fsdecode(value)
    if "\0" in text:
        raise InvalidArgumentError(f"{what} {text!r} holds a NUL character, which no file name can", 1,
                                   "invalid-argument")
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return _os.fsencode(value)
    return text


def _option_text(name, value):
    # The library parses options as the CLI's text; bool first (it is an int).
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float, str)):
        return str(value)
    if isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value):
        return ",".join(value) if value else "none"  # a list of names, e.g. attributes=["classification"]
    raise TypeError(f"option {name} must be a number, a string or a bool, got {type(value).__name__}")


def _ingest(command, inputs, archive, options, progress):
    if isinstance(inputs, (str, bytes, _os.PathLike)) or not hasattr(inputs, "__iter__"):
        inputs = [inputs]
    inputs = [_path(p, f"{command}(): an input") for p in inputs]
    archive = _path(archive, f"{command}(): the archive")
    known = set(_relief.option_names(command, False)) | set(_relief.option_names(command, True))
    given = []
    for name, value in options.items():
        if name.replace("_", "-") not in known:
            allowed = ", ".join(sorted(n.replace("-", "_") for n in known))
            raise TypeError(f"{command}() got an unexpected keyword argument '{name}' (options: {allowed})")
        if value is None:
            continue
        given.append((name, _option_text(name, value)))
    if progress is not None and not callable(progress):
        raise TypeError("progress must be callable")
    return _relief.ingest(command, inputs, archive, given, progress)


def compress(inputs, archive, *, progress=None, **options):
    """Compresses point files (PLY, LAS/LAZ, XYZ/CSV, PCD) into a new archive.

    ``inputs``: a path or a list of paths; ``archive``: the new archive's path
    (never overwritten). ``options``: as ``relief compress`` (``mode``,
    ``tolerance``, ``color_tolerance``, ``intensity_tolerance``, ``cell``, ``chunk_edge``,
    ``error_target``, ``memory`` ("512M", "2G" or a number of MiB), ``threads``,
    ``tmp``, ``columns``, ``verify``, ``allow_sparse``, ``assume_crs``, ``keep_order``
    (each chunk's points back in the order they were read), ``fast_geometry`` (octree geometry
    as chunk format 13, without format 17's plane and near classes: ~2.3x faster, ~4 % more bytes), ``crs`` (the inputs' CRS, e.g. ``"EPSG:32633"``, for files that name
    none), ``no_extra_bytes``, ``no_spool`` (read LAZ and text inputs twice rather than keep their
    decoded points in temporary files) and the encoder options). ``progress``: called about twice a second with a dict
    (points_read, points_total, points_encoded, chunks_written, bytes_written,
    seconds, phase: "scanning" (the pass over every point that fixes the grid), "reading", "encoding",
    "pyramid", "done"); an exception it raises (or Ctrl-C) stops the ingest and
    propagates, and the archive keeps the chunks committed so far (an
    incomplete scan; no archive when it stops before any is committed), as after Ctrl-C in
    the CLI.

    Returns a dict: points_read, points_decoded, chunks_written, blob_bytes,
    seconds, cell_size, chunk_edge, scan_id, spooled_bytes (decoded LAZ and text
    points kept in temporary files instead of read twice), points_skipped
    (records of the inputs that hold no point: PCD NaN points, PTX directions
    without a return), warnings.
    """
    return _ingest("compress", inputs, archive, options, progress)


def append(archive, inputs, *, progress=None, **options):
    """Adds point files to an existing archive with its grid and codec
    parameters; on failure the archive is left as it was. ``options``: as
    ``relief append`` (memory, threads, tmp, columns, verify, assume_crs,
    no_extra_bytes).
    Returns the same dict as :func:`compress`."""
    return _ingest("append", inputs, archive, options, progress)


def _polygon_text(polygon, caller):
    """The polygon argument as the library takes it: WKT text or GeoJSON text
    (a str), a GeoJSON mapping (a dict, as ``json.load`` gives one), an
    object with a ``wkt`` attribute (a shapely geometry, as GeoPandas holds
    them), or a file path (os.PathLike, or a str starting with ``@``) of WKT,
    GeoJSON or an ESRI shapefile (.shp); None: none."""
    if polygon is None:
        return ""
    if isinstance(polygon, _os.PathLike):
        return "@" + _os.fspath(polygon)
    if isinstance(polygon, str):
        return polygon
    if isinstance(polygon, dict):
        return _json.dumps(polygon)
    wkt = getattr(polygon, "wkt", None)
    if isinstance(wkt, str):
        return wkt
    raise TypeError(f"{caller}(): polygon must be WKT or GeoJSON text, a GeoJSON dict, a path, or have a .wkt "
                    f"(a shapely geometry), not {type(polygon).__name__}")


_QUERY_OPTIONS = ("threads", "skip_corrupt", "max_points", "attributes", "polygon", "polygon_crs")


def _box_values(box):
    if box is None:
        return None
    values = [float(v) for v in box]
    if len(values) not in (4, 6):
        raise InvalidArgumentError(
            f"box must be (xmin, ymin, zmin, xmax, ymax, zmax) or (xmin, ymin, xmax, ymax), got {len(values)} numbers",
            1,
            "invalid-argument",
        )
    return values


def _attribute_list(attributes):
    """The C++ side's attribute list text for a query's ``attributes``."""
    if attributes is None:
        return "all"
    if isinstance(attributes, str):
        return attributes
    names = [str(a) for a in attributes]
    for n in names:
        if not n or "," in n:
            raise _invalid(f"attribute name {n!r} is not a single name")
    return ",".join(names) if names else "none"


_EXTRA_TYPES = {"uint8": "u1", "int8": "i1", "uint16": "<u2", "int16": "<i2", "uint32": "<u4", "int32": "<i4",
                "uint64": "<u8", "int64": "<i8", "float32": "<f4", "float64": "<f8"}


def _with_extra_fields(array, described):
    """`array` viewed with each field of `described` (dicts with name, type,
    offset and size, as ``info["las"]["extra_bytes"]`` lists them) as a
    typed field beside ``extra_bytes``."""
    names = array.dtype.names or ()
    if "extra_bytes" not in names or not described:
        return array
    import numpy as np

    base, at = array.dtype.fields["extra_bytes"][:2]
    fields = {n: array.dtype.fields[n][:2] for n in names}
    for f in described:
        kind, _, count = f["type"].partition("[")
        if f["name"] in fields or kind not in _EXTRA_TYPES or f["offset"] + f["size"] > base.itemsize:
            continue
        t = np.dtype(_EXTRA_TYPES[kind])
        if count:
            t = np.dtype((t, (int(count.rstrip("]")),)))
        fields[f["name"]] = (t, at + f["offset"])
    view = np.dtype({"names": list(fields), "formats": [v[0] for v in fields.values()],
                     "offsets": [v[1] for v in fields.values()], "itemsize": array.dtype.itemsize})
    return array.view(view)


def _warn_all(messages):
    for m in messages:
        _warnings.warn(m, RuntimeWarning, stacklevel=3)


class Archive:
    """An open archive (read-only). Use :func:`open`."""

    def __init__(self, path):
        self._reader = _relief.Reader(_path(path, "open(): the archive"))
        self._info = None
        self.last_preview = None

    @property
    def path(self):
        return self._reader.path

    @property
    def closed(self):
        return self._reader.closed

    @property
    def info(self):
        """What the archive holds: the dict ``relief info --json`` prints."""
        if self._info is None:
            self._info = _json.loads(self._reader.info_json())
        return self._info

    def query(self, box=None, lod=1, batches=False, **options):
        """The points inside ``box`` as a numpy structured array.

        ``box``: (xmin, ymin, zmin, xmax, ymax, zmax), (xmin, ymin, xmax, ymax)
        for every height, or None for the whole archive; closed (points on
        its faces count). ``lod``: 1 = every point, L = a uniform ~1/L subset
        (1..1024). Fields: x, y, z (float64); red, green, blue (uint8, or
        uint16 LAS values when the source had 16-bit colours) when the
        archive has colour; intensity (float32); then each LAS attribute the
        points carry (classification, class_flags, return_number,
        number_of_returns, scan_flags, scan_angle, user_data,
        point_source_id, gps_time, nir, extra_bytes). The extra bytes (LAS
        extra bytes, and the PLY properties and PCD fields Relief keeps as
        such: normals, labels ...) are also fields of their own, by the
        names and types ``info["las"]["extra_bytes"]`` lists (views of the
        same bytes; an array field such as ``uint16[3]`` has that shape; a
        name that is already a field, and undocumented bytes, stay only in
        ``extra_bytes``). Values are raw: apply a field's ``scale`` and
        ``value_offset`` where the info gives them.

        ``batches=True``: an iterator of arrays, one per decoded batch, with
        at most a few batches in memory at a time; close it (or let it go)
        to stop the query early. Closing the archive stops it too: its next
        batch raises ValueError. ``options``: ``threads`` (decoder threads, 0
        = all cores), ``skip_corrupt`` (skip damaged chunks with a
        RuntimeWarning instead of raising CorruptDataError), ``max_points``
        (instead of ``lod``: at most that many points, from the finest level
        of the archive's level-of-detail pyramid that fits, thinned evenly
        over the box when its nodes hold more, as ``query --max-points``),
        ``attributes`` (the fields wanted beside x, y, z, by the names
        ``info["attributes"]`` lists, e.g. ``["classification", "gps_time"]`` or ``"rgb,intensity"``;
        ``[]`` or ``"none"`` for x, y, z alone; default all: the others are
        not decoded, which is faster; a name the archive lacks raises
        InvalidArgumentError), ``polygon`` (only the points inside this x-y
        area: the WKT text of a POLYGON or MULTIPOLYGON in the archive's
        coordinates, or an object with a ``wkt`` attribute such as a shapely
        geometry; GeoJSON text or a GeoJSON dict, in longitude/latitude or
        the CRS its ``crs`` member names; or a path (``pathlib.Path``, or
        ``"@file"``) of WKT, GeoJSON or an ESRI shapefile ``.shp``, whose
        ``.prj`` gives its CRS; holes by the even-odd rule; with or without
        ``box``; chunks outside it are not read; an area in another CRS than
        the archive's is converted to it; one beside the archive's bounds
        gives a RuntimeWarning), ``polygon_crs`` (the CRS the polygon's
        coordinates are in, e.g. ``"EPSG:4326"``, easting or longitude
        first; overrides the file's).
        """
        for name in options:
            if name not in _QUERY_OPTIONS:
                raise TypeError(
                    f"query() got an unexpected keyword argument '{name}' (options: {', '.join(_QUERY_OPTIONS)})"
                )
        lod = _whole(1 if lod is None else lod, "query(): lod", 1, 1024)
        threads = _whole(options.get("threads", 0), "query(): threads", 0, 1024)
        skip_corrupt = bool(options.get("skip_corrupt", False))
        max_points = options.get("max_points")
        max_points = 0 if max_points is None else _whole(max_points, "query(): max_points", 1, 1 << 50)
        attributes = _attribute_list(options.get("attributes"))
        polygon = _polygon_text(options.get("polygon"), "query")
        polygon_crs = options.get("polygon_crs") or ""
        values = _box_values(box)
        if batches:
            return self._batches(self._reader.batches(values, lod, threads, skip_corrupt, max_points, attributes,
                                                      polygon, polygon_crs))
        array, messages = self._reader.query(values, lod, threads, skip_corrupt, max_points, attributes, polygon,
                                             polygon_crs)
        _warn_all(messages)
        return self._with_extra_fields(array)

    def sections(self):
        """Where the archive's bytes go, as ``relief info --sections --json``
        gives them under ``"sections"``: ``file_bytes``, ``blob_bytes``,
        ``framing_bytes``, ``pyramid_bytes``, ``container_bytes`` (SQLite's
        share) and ``sections``, a list of ``{"id", "name", "maps", "bytes",
        "chunks"}`` (``maps``: one of the paper's maps, the base layer).
        Reads each blob's header and section table only (``relief check``
        verifies the blobs).
        """
        return _json.loads(self._reader.sections_json())

    def stats(self, box=None, *, attributes=None, threads=0, skip_corrupt=False, polygon=None, polygon_crs=None):
        """What the points (in ``box``, as ``query`` takes it) hold, as ``relief
        stats --json``: a dict with ``points``; ``x``, ``y``, ``z`` and each
        ranged attribute as ``{"count", "min", "max", "mean"}``;
        ``classification``, ``return_number``, ``number_of_returns`` as
        ``{value: count}`` (values as strings, JSON's keys); flag counts;
        ``point_sources`` (distinct IDs); ``extra_bytes`` by field name.
        ``attributes``: only those (as ``query``), and only they are decoded,
        so asking for few is quick. ``polygon`` and ``polygon_crs``: only the
        points inside this area, as ``query``.
        """
        threads = _whole(threads, "stats(): threads", 0, 1024)
        text, messages = self._reader.stats_json(_box_values(box), threads, bool(skip_corrupt),
                                                 _attribute_list(attributes), _polygon_text(polygon, "stats"),
                                                 polygon_crs or "")
        _warn_all(messages)
        return _json.loads(text)

    def _batches(self, stream):
        # A generator, so an abandoned iteration closes the query (the
        # worker thread stops) when the generator is collected or closed.
        try:
            for array, messages in stream:
                _warn_all(messages)
                if array is not None:
                    yield self._with_extra_fields(array)
        finally:
            stream.close()

    def _with_extra_fields(self, array):
        """`array` viewed with each described extra bytes field as a typed field."""
        las = self.info.get("las") or {}
        return _with_extra_fields(array, las.get("extra_bytes") or [])

    def preview(self, box=None, *, path=None, width=1024, view="top", azimuth=30, elevation=35, lod=None,
                threads=0):
        """A quick-look image of the archive, or of the points inside ``box``,
        as ``relief preview`` draws it (the same library call): an (height,
        width, 3) uint8 RGB array, rows from the top.

        ``box`` as for :meth:`query` (the top view shows its x/y extent;
        None: the archive's bounds). ``view``: "top" (north up, with a scale
        bar) or "oblique" (rotated by ``azimuth`` degrees about z, tilted by
        ``elevation`` above the horizon). ``width``: 16..8192 pixels, the
        height following the aspect ratio. ``lod``: about 1/lod of the
        points; None: from an archive's level-of-detail pyramid the finest
        level that gives at most 2 points per pixel, else lod 16. Colours are
        the points' RGB when the archive has colour, else a height colour
        map, hill-shaded. ``path``: also write the image, PNG (.png) or JPEG
        (.jpg, .jpeg) by extension, replacing the file once it is complete.
        The figures of the drawing (points read and drawn, chunks decoded,
        bytes read, pixel size, level of detail) are in ``last_preview``.
        """
        lod = 0 if lod is None else _whole(lod, "preview(): lod", 1, 1024)
        width = _whole(width, "preview(): width", 16, 8192)
        threads = _whole(threads, "preview(): threads", 0, 1024)
        encoding = ""
        if path is not None:
            ext = _os.path.splitext(str(path))[1].lower()
            if ext not in (".png", ".jpg", ".jpeg"):
                raise _invalid(f"preview(): {path}: the image is written as PNG (.png) or JPEG (.jpg, .jpeg)")
            encoding = "png" if ext == ".png" else "jpeg"
        image, figures, data = self._reader.preview(_box_values(box), lod, width, str(view),
                                                    float(azimuth), float(elevation), threads, encoding)
        self.last_preview = figures
        if data is not None:
            # Beside the image, named after this host and process (as the
            # library names its temporary files: hosts may share the directory).
            host = "".join(c if (c.isascii() and c.isalnum()) or c in "._-" else "_" for c in _socket.gethostname())[:64] or "host"
            tmp = f"{path}.tmp-{host}-{_os.getpid()}"
            try:
                with _builtins.open(tmp, "wb") as f:
                    f.write(data)
                _os.replace(tmp, str(path))
            except OSError as e:
                if _os.path.exists(tmp):
                    _os.unlink(tmp)
                raise _make_error(2, "io-error", f"{path}: cannot write: {e.strerror or e}") from e
        return image

    def close(self):
        """Closes the archive; later queries raise ValueError, and so does the
        next batch of a ``query(batches=True)`` iteration still in progress
        (its query is stopped here)."""
        self._reader.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self):
        state = "closed" if self.closed else "open"
        return f"<relief.Archive {self.path!r} ({state})>"


# ---- relief.write: a structured array (as Archive.query returns) to a file.

# The fields with a meaning of their own, and the type each is written as.
_POINT_FIELDS = {
    "x": "<f8", "y": "<f8", "z": "<f8", "intensity": "<f4", "classification": "u1", "class_flags": "u1",
    "return_number": "u1", "number_of_returns": "u1", "scan_flags": "u1", "scan_angle": "<i4",
    "user_data": "u1", "point_source_id": "<u2", "gps_time": "<f8", "nir": "<u2",
}
_COLOUR_FIELDS = ("red", "green", "blue")
# LAS Extra Bytes data types (LAS 1.4 R15, table 24) of numpy scalar types.
_EXTRA_TYPE_IDS = {"u1": 1, "i1": 2, "u2": 3, "i2": 4, "u4": 5, "i4": 6, "u8": 7, "i8": 8, "f4": 9, "f8": 10}


def _extra_descriptor(name, data_type, options=0):
    """One 192-byte Extra Bytes descriptor (LAS 1.4 R15, section 2.5)."""
    raw = name.encode("ascii", "strict") if data_type else b""
    if len(raw) > 32:
        raise _invalid(f"write(): extra bytes field name '{name}' is longer than LAS's 32 characters")
    d = bytearray(192)
    d[2] = data_type
    d[3] = options
    d[4:4 + len(raw)] = raw
    return bytes(d)


def _undocumented(size):
    """Descriptors of `size` undocumented bytes (at most 255 each)."""
    return [_extra_descriptor("", 0, min(255, size - k)) for k in range(0, size, 255)]


def _extra_type(name, dt):
    """The LAS data type of a field of numpy type `dt`, and its size."""
    import numpy as np

    base, shape = (dt.subdtype if dt.subdtype else (dt, ()))
    if base.kind == "b":
        base = np.dtype("u1")  # a flag: 0 or 1
    key = f"{base.kind}{base.itemsize}"
    count = int(np.prod(shape)) if shape else 1
    if base.kind not in "iuf" or key not in _EXTRA_TYPE_IDS or len(shape) > 1 or count > 3:
        raise _invalid(
            f"write(): field '{name}' ({dt}) is neither a point attribute nor an extra bytes field LAS can "
            "describe (a number, or 2 or 3 of them)")
    return _EXTRA_TYPE_IDS[key] + 10 * (count - 1), base.itemsize * count, base.newbyteorder("<"), shape


def _checked(name, values, target):
    """`values` as the C-contiguous array of type `target`, refusing what it cannot hold."""
    import numpy as np

    t = np.dtype(target)
    kind = values.dtype.kind
    if t.kind == "f":
        if kind not in "iuf":
            raise _invalid(f"write(): field '{name}' must be numeric, not {values.dtype}")
        out = np.ascontiguousarray(values, dtype=t)
        bad = ~np.isfinite(out)
        if bad.any():
            raise _invalid(
                f"write(): field '{name}' has a non-finite value at point {int(np.argmax(bad))}")
        return out
    if kind not in "iub":
        raise _invalid(f"write(): field '{name}' must hold integers ({t}), not {values.dtype}")
    info = np.iinfo(t)
    if len(values) and (values.min() < info.min or values.max() > info.max):
        at = int(np.argmax((values < info.min) | (values > info.max)))
        raise _invalid(
            f"write(): field '{name}' has {values[at]} at point {at}, outside {info.min}..{info.max}")
    return np.ascontiguousarray(values, dtype=t)


def check(path):
    """Verifies a whole archive as ``relief check`` does, trusting no part of
    it: SQLite's integrity check, the metadata and CRS checksums, every chunk
    and pyramid blob's CRC-32, and the spatial index against the chunk table.
    Returns ``{"format_version", "intact", "checked", "problems"}`` (a line
    per check made and per damage found); raises only when the file cannot be
    checked at all (missing, not an archive, a newer format)."""
    return _relief.check(_path(path, "check(): the archive"))


def stats(path, *, attributes=None):
    """What a point file (LAS, LAZ, PLY, XYZ/CSV, PCD) holds, summarised as
    ``Archive.stats`` summarises an archive (the same dict): compare the two
    to check an archive against its source."""
    return _json.loads(_relief.file_stats_json(_path(path, "stats(): the file"), _attribute_list(attributes)))


def read(path, *, attributes=None, columns=None, extra_bytes=True, batches=False, batch_points=1 << 20):
    """Every point of a point file as a numpy structured array.

    Any format ``relief compress`` reads, by extension: ``.las``, ``.laz``
    (COPC too), ``.ply``, ``.xyz``/``.txt``/``.csv``/``.pts``, ``.pcd``,
    ``.ptx``, ``.e57``, read by the library's own readers, as they read
    inputs (the same rules, checks and warnings, which come as
    RuntimeWarnings). The fields are those :meth:`Archive.query` gives for
    an archive of the file: x, y, z; red, green, blue (uint8, or uint16 LAS
    values for 16-bit colours); intensity; the LAS attributes the points
    carry; ``extra_bytes`` with a typed field for each described one.
    ``attributes``: only those beside x, y, z (as ``query`` takes them);
    ``columns``: the columns of a text file, as ``compress`` takes them
    (``"x,y,z,i,r,g,b"``); ``extra_bytes=False`` drops the extra fields.
    The whole file is read into memory, unless ``batches=True``: then an
    iterator of arrays of at most ``batch_points`` points each, in the
    file's order, one batch in memory at a time (close it, or let it go, to
    stop early). A file that cannot be opened raises here, a later error
    when its batch is reached.
    """
    if batches:
        it = _relief.read_batches(_path(path, "read(): the file"), _attribute_list(attributes), columns or "",
                                  bool(extra_bytes), _whole(batch_points, "read(): batch_points", 1, 1 << 40))
        return _file_batches(it, _described(it.extra_fields()))
    array, messages, described = _relief.read_points(_path(path, "read(): the file"), _attribute_list(attributes),
                                                     columns or "", bool(extra_bytes))
    _warn_all(messages)
    return _with_extra_fields(array, _described(described))


def _described(fields):
    """(name, type, offset, size) tuples as ``info["las"]["extra_bytes"]`` lists fields."""
    return [{"name": n, "type": t, "offset": o, "size": s} for n, t, o, s in fields]


def _file_batches(it, described):
    # A generator, so an abandoned iteration closes the file when the
    # generator is collected or closed.
    try:
        for array, messages in it:
            _warn_all(messages)
            if array is not None:
                yield _with_extra_fields(array, described)
    finally:
        it.close()


def write(path, points, *, crs=None, scale=None):
    """Writes a numpy structured array of points to a point file.

    The format follows the extension, as ``relief decompress`` writes it:
    ``.las``, ``.laz``, ``.ply``, ``.xyz``/``.txt``/``.csv``. ``points``:
    fields x, y, z (numbers, finite) and any of those
    :meth:`Archive.query` gives (red, green, blue as uint8, or up to 65535
    for 16-bit LAS colours; intensity; the LAS attributes classification,
    class_flags, return_number, number_of_returns, scan_flags, scan_angle
    (thousandths of a degree), user_data, point_source_id, gps_time, nir),
    each checked to fit its type (a value that does not raises
    InvalidArgumentError naming the field and the point; the LAS writer
    refuses values its point format cannot hold). Every other field that is
    a number (a bool as uint8), or 2 or 3 of them, becomes a LAS extra bytes field of its name
    and type (PLY properties, text columns); a query's opaque
    ``extra_bytes`` is written as it is, described by the typed fields that
    view it. ``crs``: WKT or "EPSG:<code>" for LAS/LAZ. ``scale``: the LAS
    coordinate resolution (default: 0.1 mm, coarser when the extent needs
    it). An existing file is replaced once the new one is complete.
    What the format cannot hold as given (a LAS intensity outside 0..65535,
    clamped, or with a fraction, rounded) is said by a RuntimeWarning.
    Returns the number of points written.
    """
    import numpy as np

    if not isinstance(points, np.ndarray) or points.dtype.names is None or points.ndim != 1:
        raise _invalid("write(): points must be a 1-D numpy structured array")
    names = points.dtype.names
    missing = [k for k in ("x", "y", "z") if k not in names]
    if missing:
        raise _invalid(f"write(): the points have no field {', '.join(missing)}")
    columns = {}
    for name in names:
        if name in _POINT_FIELDS:
            columns[name] = _checked(name, points[name], _POINT_FIELDS[name])
    colours = [k for k in _COLOUR_FIELDS if k in names]
    if colours and len(colours) != 3:
        raise _invalid(f"write(): colour needs red, green and blue, the points have {', '.join(colours)}")
    if colours:
        # 16-bit LAS colours as a query gives them (uint16), or any integers
        # above 255; other integer types holding 0..255 are 8-bit levels.
        wide = any(points[k].dtype == np.uint16 for k in colours) or any(
            points[k].dtype.kind in "iu" and len(points) and points[k].max() > 255 for k in colours)
        for k in colours:
            columns[k] = _checked(k, points[k], "<u2" if wide else "u1")

    # Extra bytes: the opaque block of a query first (described by the typed
    # fields that view it, gaps undocumented), then every other field.
    fields = points.dtype.fields
    extra_parts, descriptors = [], []
    block_at, block_size = None, 0
    if "extra_bytes" in names and fields["extra_bytes"][0].kind == "V" and fields["extra_bytes"][0].names is None:
        block_at, block_size = fields["extra_bytes"][1], fields["extra_bytes"][0].itemsize
        extra_parts.append(np.ascontiguousarray(points["extra_bytes"]).view(np.uint8).reshape(len(points), block_size))
    views, others = [], []
    for name in names:
        if name in _POINT_FIELDS or name in _COLOUR_FIELDS or name == "extra_bytes":
            continue
        dt, at = fields[name][:2]
        if block_at is not None and block_at <= at and at + dt.itemsize <= block_at + block_size:
            views.append((at - block_at, name, dt))
        else:
            others.append((name, dt))
    done = 0
    for at, name, dt in sorted(views):
        data_type, size, _, _ = _extra_type(name, dt)
        if at < done:
            raise _invalid(f"write(): extra bytes field '{name}' overlaps the one before it")
        descriptors += _undocumented(at - done)
        descriptors.append(_extra_descriptor(name, data_type))
        done = at + size
    if descriptors:
        descriptors += _undocumented(block_size - done)
    described = bool(descriptors) or block_at is None
    for name, dt in others:
        data_type, size, little, _ = _extra_type(name, dt)
        values = np.ascontiguousarray(points[name], dtype=little)  # (n,) or (n, count)
        extra_parts.append(values.view(np.uint8).reshape(len(points), size))
        if not described:  # an undescribed block before it
            descriptors += _undocumented(block_size)
            described = True
        descriptors.append(_extra_descriptor(name, data_type))
    extra = None
    if extra_parts:
        extra = np.ascontiguousarray(np.concatenate(extra_parts, axis=1) if len(extra_parts) > 1 else extra_parts[0])
    written, messages = _relief.write_points(_path(path, "write(): the file"), columns, extra,
                                             b"".join(descriptors), crs or "",
                                             0.0 if scale is None else float(scale))
    _warn_all(messages)
    return written


def retain_freed_memory():
    """Keep freed blocks up to 32 MiB in the C allocator for reuse.

    What the ``relief`` command does first thing (``relief/types.h``): with
    glibc's defaults each chunk's decoding buffers go back to the kernel when
    freed and the next chunk faults in fresh zeroed pages, which on some
    machines is a third of decoding a whole archive. It is a setting of the
    whole process (glibc ``mallopt``: mmap threshold 32 MiB, trim threshold
    256 MiB, one arena for every thread; memory freed after the peak then
    stays with the process), so
    importing relief does not make it: call it once in a program that reads
    or writes many chunks. Does nothing without glibc.
    """
    _relief.retain_freed_memory()


def open(path):  # noqa: A001 (the package's verb, as relief.open)
    """Opens an archive read-only (also while another process appends)."""
    return Archive(path)
