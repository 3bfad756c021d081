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

import json as _json
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
    "compress",
    "open",
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


def _option_text(name, value):
    # The library parses options as the CLI's text; bool first (it is an int).
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float, str)):
        return str(value)
    raise TypeError(f"option {name} must be a number, a string or a bool, got {type(value).__name__}")


def _ingest(command, inputs, archive, options, progress):
    if isinstance(inputs, (str, bytes)) or not hasattr(inputs, "__iter__"):
        inputs = [inputs]
    inputs = [str(p) for p in inputs]
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
    return _relief.ingest(command, inputs, str(archive), given, progress)


def compress(inputs, archive, *, progress=None, **options):
    """Compresses point files (PLY, LAS/LAZ, XYZ/CSV, PCD) into a new archive.

    ``inputs``: a path or a list of paths; ``archive``: the new archive's path
    (never overwritten). ``options``: as ``relief compress`` (``mode``,
    ``tolerance``, ``color_tolerance``, ``cell``, ``chunk_edge``,
    ``error_target``, ``memory`` ("512M", "2G" or a number of MiB), ``threads``,
    ``tmp``, ``columns``, ``verify``, ``allow_sparse``, ``assume_crs``,
    ``no_extra_bytes`` and the encoder options). ``progress``: called about twice a second with a dict
    (points_read, points_total, chunks_written, bytes_written, seconds,
    phase); an exception it raises (or Ctrl-C) stops the ingest and
    propagates, and the archive keeps the chunks committed so far (an
    incomplete scan), as after Ctrl-C in the CLI.

    Returns a dict: points_read, points_decoded, chunks_written, blob_bytes,
    seconds, cell_size, chunk_edge, scan_id, warnings.
    """
    return _ingest("compress", inputs, archive, options, progress)


def append(archive, inputs, *, progress=None, **options):
    """Adds point files to an existing archive with its grid and codec
    parameters; on failure the archive is left as it was. ``options``: as
    ``relief append`` (memory, threads, tmp, columns, verify, assume_crs,
    no_extra_bytes).
    Returns the same dict as :func:`compress`."""
    return _ingest("append", inputs, archive, options, progress)


_QUERY_OPTIONS = ("threads", "skip_corrupt", "max_points")


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


def _warn_all(messages):
    for m in messages:
        _warnings.warn(m, RuntimeWarning, stacklevel=3)


class Archive:
    """An open archive (read-only). Use :func:`open`."""

    def __init__(self, path):
        self._reader = _relief.Reader(str(path))
        self._info = None

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
        to stop the query early. ``options``: ``threads`` (decoder threads, 0
        = all cores), ``skip_corrupt`` (skip damaged chunks with a
        RuntimeWarning instead of raising CorruptDataError), ``max_points``
        (instead of ``lod``: at most that many points, from the finest level
        of the archive's level-of-detail pyramid that fits).
        """
        for name in options:
            if name not in _QUERY_OPTIONS:
                raise TypeError(
                    f"query() got an unexpected keyword argument '{name}' (options: {', '.join(_QUERY_OPTIONS)})"
                )
        threads = options.get("threads", 0)
        skip_corrupt = bool(options.get("skip_corrupt", False))
        max_points = options.get("max_points") or 0
        values = _box_values(box)
        if batches:
            return self._batches(self._reader.batches(values, lod, threads, skip_corrupt, max_points))
        array, messages = self._reader.query(values, lod, threads, skip_corrupt, max_points)
        _warn_all(messages)
        return self._with_extra_fields(array)

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

    _EXTRA_TYPES = {"uint8": "u1", "int8": "i1", "uint16": "<u2", "int16": "<i2", "uint32": "<u4", "int32": "<i4",
                    "uint64": "<u8", "int64": "<i8", "float32": "<f4", "float64": "<f8"}

    def _with_extra_fields(self, array):
        """`array` viewed with each described extra bytes field as a typed field."""
        names = array.dtype.names or ()
        las = self.info.get("las") or {}
        described = las.get("extra_bytes") or []
        if "extra_bytes" not in names or not described:
            return array
        import numpy as np

        base, at = array.dtype.fields["extra_bytes"][:2]
        fields = {n: array.dtype.fields[n][:2] for n in names}
        for f in described:
            kind, _, count = f["type"].partition("[")
            if f["name"] in fields or kind not in self._EXTRA_TYPES or f["offset"] + f["size"] > base.itemsize:
                continue
            t = np.dtype(self._EXTRA_TYPES[kind])
            if count:
                t = np.dtype((t, (int(count.rstrip("]")),)))
            fields[f["name"]] = (t, at + f["offset"])
        view = np.dtype({"names": list(fields), "formats": [v[0] for v in fields.values()],
                         "offsets": [v[1] for v in fields.values()], "itemsize": array.dtype.itemsize})
        return array.view(view)

    def close(self):
        """Closes the archive; later queries raise ValueError."""
        self._reader.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self):
        state = "closed" if self.closed else "open"
        return f"<relief.Archive {self.path!r} ({state})>"


def open(path):  # noqa: A001 (the package's verb, as relief.open)
    """Opens an archive read-only (also while another process appends)."""
    return Archive(path)
