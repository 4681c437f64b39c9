"""The transforms table: one row per input of a batch run, as Parquet or CSV.

Each row says where an input went and by which similarity: ``x -> R (x - center) / scale``, with
``R`` the identity unless the run asked for a rotation. Every number is stored in float64 without
loss (Parquet natively; CSV with Python's shortest round-trip ``repr``), so
:meth:`Transform.apply` reproduces the written output from the input to the last bit and
:meth:`Transform.invert` maps it back. A row's similarity is a :class:`jaxpose.Pose`
(:attr:`Transform.pose`). The columns, in order (:data:`COLUMNS`):

=================  =======  ===============================================================
column             type     meaning
=================  =======  ===============================================================
input              str      the input file (absolute path: its folder's real path, links and ``..``
                            resolved, and its own name, a link to a file named as the link)
output             str      the normalized file (absolute path); empty when the input failed
status             str      ``ok`` or ``failed``
error              str      why the input failed (one line); empty when ok
center_x/_y/_z     float64  the center, in the input's units (NaN when failed)
scale              float64  the scale, in the input's units (NaN when failed)
valid              bool     the estimator's validity flag (:class:`jaxpose.Pose` ``valid``)
converged          bool     the solver reached its tolerance (always true for NumPy estimators)
kind               str      ``mesh`` or ``points`` (empty when the input could not be read)
vertices, faces    int64    size of the input as read (0 when unread)
method             str      the method asked for (``robust`` by default)
center_method      str      the center estimator used
scale_method       str      the scale estimator used
gamma, nu          float64  OCSVM parameters (used by ``ocsvm`` only)
count, seed        int64    OCSVM samples and seed (used by ``ocsvm`` only)
sampling           str      OCSVM surface sampling (used by ``ocsvm`` only)
resolution         int64    the grid/voxel resolution asked for; null for the estimator's default
seconds            float64  seconds to read, normalize and encode this input in its worker
worker             str      ``host:pid`` of the process that did it
worker_peak_mb     float64  that process's peak resident memory so far, MiB
input_size         int64    bytes of the input when it was read (a local .gltf's with those of
                            the buffer files it names; its time the latest, its SHA-256 of all)
input_mtime_ns     int64    its modification time, ns since the epoch
input_sha256       str      its SHA-256 (only with ``--check hash``; empty otherwise)
version            str      the jaxpose version of the worker that made the row
options            str      every option of the run that made it, as JSON (``NormalizeOptions``
                            fields and the output ``format``): what a rerun compares
=================  =======  ===============================================================

Size, modification time and SHA-256 are those of the bytes the worker read (checked unchanged
during the read). Paths that are not valid UTF-8 (bytes names on Linux) are stored with their
undecodable bytes written ``\\xNN``. Tables written before ``version`` and ``options`` existed
read with those None.

With a rotation (``--rotation``), four more come after ``resolution``: ``rotation_method`` (str),
``r00`` ... ``r22`` (float64, row-major; the rows of R are the canonical axes) and ``ambiguity``
(float64 in [0, 1]).
"""
from __future__ import annotations

import csv
import importlib.util
import io
import math
import os
from typing import NamedTuple

import numpy as np

from .._validate import InvalidInputError
from ..errors import UsageError
from ..pose.result import Pose, Status

__all__ = ["COLUMNS", "ROTATION_COLUMNS", "Transform", "read_transforms", "merge_transforms", "write_transforms",
           "table_format", "default_table_name", "has_parquet", "check_replaceable"]

_BASE = (
    ("input", "str"), ("output", "str"), ("status", "str"), ("error", "str"),
    ("center_x", "float"), ("center_y", "float"), ("center_z", "float"), ("scale", "float"),
    ("valid", "bool"), ("converged", "bool"), ("kind", "str"), ("vertices", "int"), ("faces", "int"),
    ("method", "str"), ("center_method", "str"), ("scale_method", "str"), ("gamma", "float"),
    ("nu", "float"), ("count", "int"), ("seed", "int"), ("sampling", "str"), ("resolution", "int"),
)
_ROTATION = (("rotation_method", "str"),) + tuple((f"r{i}{j}", "float") for i in range(3) for j in range(3)) + (
    ("ambiguity", "float"),)
_TAIL = (
    ("seconds", "float"), ("worker", "str"), ("worker_peak_mb", "float"),
    ("input_size", "int"), ("input_mtime_ns", "int"), ("input_sha256", "str"), ("version", "str"),
    ("options", "str"),
)
_OPTIONAL = ("version", "options")  # later additions: absent from older tables
COLUMNS = tuple(name for name, _ in _BASE + _TAIL)
ROTATION_COLUMNS = tuple(name for name, _ in _ROTATION)
_TYPES = dict(_BASE + _ROTATION + _TAIL)
_FIELDS = tuple(name for name, _ in _BASE + _ROTATION + _TAIL)


class Transform(NamedTuple("_Row", [(name, object) for name in _FIELDS])):
    """One row of the transforms table: the columns as fields (rotation fields None without one),
    and :attr:`pose`, the row's similarity as a :class:`jaxpose.Pose` (the library's one
    similarity type).

    ``center``, ``rotation``, ``matrix``, ``apply`` and ``invert`` are shorthands of that Pose,
    kept so that code written against earlier tables runs unchanged: ``row.apply(x)`` is
    ``row.pose.apply(x)`` (bit for bit the written output, which the file holds rounded by its
    format: float32 or a fixed number of decimals), ``row.invert(y)`` is
    ``row.pose.inverse().apply(y)``, ``row.matrix`` is ``row.pose.matrix``; the last three
    refuse a failed row.

    Example::

        row = jaxpose.read_transforms("normalized/")[0]
        pose = row.pose                                   # a jaxpose.Pose, float64
        back = pose.inverse().apply(trimesh.load(row.output).vertices)
    """

    __slots__ = ()

    @classmethod
    def from_record(cls, record: dict) -> "Transform":
        """A row from a dict of columns (missing ones None; a failed row's center and scale NaN)."""
        return cls(**{name: _clean(_cell(record, name), name) for name in _FIELDS})

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def pose(self) -> Pose:
        """The row's similarity x -> R (x - center) / scale as a host :class:`jaxpose.Pose`
        (NumPy: floats float64 as stored, flags bool, codes int64; :func:`jaxpose.pose.result.host`).

        ``valid`` is the stored flag (False for a failed row, whose center and scale are NaN);
        ``status`` is ``Status.OK`` for a valid row and ``Status.NOT_FINITE`` otherwise (the table
        stores no other reason); ``rotation`` (3, 3) and ``ambiguity`` when the run asked for a
        rotation, else None; ``iterations`` 0 and ``count`` None (not stored).
        """
        center = np.array([self.center_x, self.center_y, self.center_z], dtype=np.float64)
        scale = np.asarray(self.scale, dtype=np.float64)
        rotation = ambiguity = None
        if self.r00 is not None:
            rotation = np.array([[getattr(self, f"r{i}{j}") for j in range(3)] for i in range(3)], dtype=np.float64)
            ambiguity = np.asarray(math.nan if self.ambiguity is None else self.ambiguity, dtype=np.float64)
        finite = bool(np.all(np.isfinite(center)) and np.isfinite(scale) and scale > 0)
        valid = self.ok and finite and self.valid is not False
        status = Status.OK if valid else Status.NOT_FINITE
        return Pose(center, scale, np.asarray(self.converged is not False), np.asarray(valid), np.asarray(0, np.int64),
                    ambiguity, rotation, np.asarray(int(status), np.int64))

    @property
    def center(self) -> np.ndarray:
        """(3,) float64: ``pose.center`` (NaN for a failed row)."""
        return self.pose.center

    @property
    def rotation(self):
        """(3, 3) float64 or None: ``pose.rotation``."""
        return self.pose.rotation

    @property
    def matrix(self) -> np.ndarray:
        """(4, 4) float64: ``pose.matrix``, the matrix of x -> R (x - center) / scale."""
        self._require_ok()
        return self.pose.matrix

    def apply(self, points) -> np.ndarray:
        """Input coordinates (n, 3) -> output coordinates (n, 3) float64: ``pose.apply(points)``,
        computed as the output was (:func:`jaxpose.mesh.normalized_points`), so bit-identical to it."""
        self._require_ok()
        return self.pose.apply(np.asarray(points, np.float64))

    def invert(self, points) -> np.ndarray:
        """Output coordinates (n, 3) -> input coordinates (n, 3) float64: ``pose.inverse().apply(points)``
        = scale R^T y + center (the center added last: exact to the last bit for outputs of inputs
        far from the origin)."""
        self._require_ok()
        return self.pose.inverse().apply(np.asarray(points, np.float64))

    def _require_ok(self):
        if not self.ok:
            raise InvalidInputError(f"{self.input}: no transform (the input failed: {self.error})")


def has_parquet() -> bool:
    """Whether pyarrow is installed (Parquet tables); found without importing it."""
    return importlib.util.find_spec("pyarrow") is not None


def default_table_name() -> str:
    """``transforms.parquet`` when pyarrow is installed, else ``transforms.csv``."""
    return "transforms.parquet" if has_parquet() else "transforms.csv"


def table_format(path) -> str:
    """``"parquet"`` or ``"csv"`` from a table path's suffix; refuses others (UsageError) and Parquet
    without pyarrow (InvalidInputError)."""
    suffix = os.path.splitext(str(path))[1].lower()
    if suffix == ".csv":
        return "csv"
    if suffix in (".parquet", ".pq"):
        if not has_parquet():
            raise InvalidInputError(f"{path}: a Parquet table needs pyarrow (pip install pyarrow); "
                                    "or name a .csv table")
        return "parquet"
    raise UsageError(f"{path}: a table must end in .parquet or .csv, got {suffix or '(no suffix)'!r}")


def check_replaceable(path, force=False):
    """Refuse a table path that a run could not, or must not, write its table to at its end.

    Args:
      path: the table's path or URL.
      force: replace an existing file even when it is not a transforms table.

    Raises:
      UsageError (an InvalidInputError): `path` is a folder; or (unless `force`) a file that is not empty and not
        a transforms table (no ``input``, ``output`` and ``status`` columns): a run writes its
        table last, after all the work, and must not replace a file that it did not write.
    """
    path = location_of(path)
    if path.is_dir():
        raise UsageError(f"the table {path} is a folder; name a .parquet or .csv file")
    if force or not path.is_file():
        return
    data = path.read_bytes()
    if not data:
        return
    try:
        if table_format(path) == "parquet":
            import pyarrow.parquet as pq

            names = pq.read_schema(io.BytesIO(data)).names
        else:
            names = next(csv.reader([data.split(b"\n", 1)[0].decode("utf-8-sig")]), [])
    except Exception:  # not Parquet, not UTF-8 text: not a table
        names = []
    if not {"input", "output", "status"} <= set(names):
        raise UsageError(f"the table {path} exists and is not a transforms table; name another file, "
                         "or use --force / force=True to replace it")


def _columns(rotation):
    return COLUMNS[:len(_BASE)] + (ROTATION_COLUMNS if rotation else ()) + COLUMNS[len(_BASE):]


def _cell(row, name):
    value = row.get(name) if isinstance(row, dict) else getattr(row, name)
    if isinstance(value, str) and value == "" and _TYPES[name] != "str":
        return None
    kind = _TYPES[name]
    if value is None:
        return None
    if kind == "float":
        return float(value)
    if kind == "int":
        return int(value)
    if kind == "bool":
        return bool(value)
    return _storable(str(value))


def _storable(text):
    """`text` as valid UTF-8: a path's undecodable bytes (surrogate escapes) as ``\\xNN``."""
    try:
        text.encode("utf-8")
        return text
    except UnicodeEncodeError:
        return os.fsencode(text).decode("utf-8", "backslashreplace")


def write_transforms(rows, path=None, rotation=None) -> bytes:
    """The table of `rows` as bytes (Parquet or CSV, from `path`'s suffix); the caller writes them.

    Args:
      rows: dicts keyed by column name (missing keys are null) or :class:`Transform` rows.
      path: the table's file name (only its suffix is used: ``.parquet`` or ``.csv``).
      rotation: include the rotation columns; default: when any row has a ``rotation_method``.

    Returns:
      The encoded table.
    """
    rows = list(rows)
    kind = table_format(path)
    if rotation is None:
        rotation = any(_cell(r, "rotation_method") for r in rows)
    names = _columns(rotation)
    data = {name: [_cell(r, name) for r in rows] for name in names}
    if kind == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        types = {"str": pa.string(), "float": pa.float64(), "int": pa.int64(), "bool": pa.bool_()}
        schema = pa.schema([(name, types[_TYPES[name]]) for name in names])
        sink = io.BytesIO()
        pq.write_table(pa.Table.from_pydict(data, schema=schema), sink)
        return sink.getvalue()
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(names)
    for i in range(len(rows)):
        writer.writerow([_csv_text(data[name][i]) for name in names])
    return text.getvalue().encode("utf-8")


def _csv_text(value):
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)  # shortest string that reads back to the same float64
    return str(value)


def _csv_value(text, kind):
    if text == "":
        return "" if kind == "str" else None
    if kind == "float":
        return float(text)
    if kind == "int":
        return int(text)
    if kind == "bool":
        return text == "true"
    return text


def read_transforms(path) -> list:
    """Read transforms tables (Parquet or CSV, from the suffix) back as :class:`Transform` rows.

    Args:
      path: a table written by :func:`jaxpose.normalize_files` / ``jaxpose normalize ... -o OUTDIR``;
        or a folder, meaning its tables (``transforms*.parquet``, ``transforms*.csv``: the default
        names, shards' included), oldest first; or a list of tables and folders.

    Returns:
      list of :class:`Transform`: one table's rows in its order (the order of the inputs); several
      tables' rows merged by :func:`merge_transforms` (the tables of N shards: the rows of the
      unsharded run).

    Raises:
      InvalidInputError: a missing file, a folder without tables, an unknown suffix, or a file that
        is not such a table.

    Example::

        rows = jaxpose.read_transforms("normalized/transforms.parquet")
        row = rows[0]; row.center, row.scale, row.matrix     # (3,), float, (4, 4)
        back = row.invert(trimesh.load(row.output).vertices)  # the input's coordinates
        everything = jaxpose.read_transforms(["shard0/", "shard1/", "shard2/"])
    """
    from ..io.remote import RemotePath

    if isinstance(path, (str, os.PathLike, RemotePath)) and not location_of(path).is_dir():
        return _read_table(path)
    tables = _tables(path)
    return merge_transforms([_read_table(t) for t in tables])


def merge_transforms(tables) -> list:
    """The rows of several tables as one table.

    Rows are concatenated in order; an ok row is dropped when a later ok row names the same
    output (a later run replaced that file), a failed row when a later row has the same input (a
    later run tried it again). Shards' tables have neither: they concatenate.

    Args:
      tables: lists of :class:`Transform` (or dicts of columns).

    Returns:
      list of :class:`Transform`.
    """
    rows = [r if isinstance(r, Transform) else Transform.from_record(r) for table in tables for r in table]
    last_input, last_output = {}, {}
    for i, row in enumerate(rows):
        last_input[row.input] = i
        if row.ok:
            last_output[row.output] = i
    return [row for i, row in enumerate(rows)
            if (last_output[row.output] == i if row.ok else last_input[row.input] == i)]


def _tables(path):
    """The table files `path` names: itself, a folder's default-named tables, or a list's."""
    from ..io.remote import RemotePath, modified_ns

    if not isinstance(path, (str, os.PathLike, RemotePath)):
        if isinstance(path, bytes) or not hasattr(path, "__iter__"):  # None, a number: not a list of paths
            raise InvalidInputError(f"a transforms table, a folder of them or a list of those, got {path!r}")
        return [t for p in path for t in _tables(p)]
    path = location_of(path)
    if not path.is_dir():
        return [path]
    if isinstance(path, RemotePath):
        listed = [(RemotePath(path.fs, i["name"]), modified_ns(i) or 0) for i in path.fs.ls(path.path, detail=True)
                  if i.get("type") == "file"]
    else:
        listed = [(p, p.stat().st_mtime_ns) for p in path.iterdir() if p.is_file()]
    found = [(when, p.name, p) for p, when in listed if p.name.startswith("transforms")
             and p.suffix.lower() in (".parquet", ".pq", ".csv")]
    if not found:
        raise InvalidInputError(f"no transforms table (transforms*.parquet, transforms*.csv) in the folder {path}")
    return [p for _, _, p in sorted(found, key=lambda t: t[:2])]


def location_of(path):
    """A table's path: local, or remote for a URL (:func:`jaxpose.io.remote.location`)."""
    from ..io.remote import location

    return location(path)


def _read_table(path):
    path = location_of(path)
    if not path.exists():  # before the suffix: a missing folder ("out/") is missing, not a bad suffix
        raise InvalidInputError(f"no such table or folder: {path}")
    kind = table_format(path)
    if not path.is_file():
        raise InvalidInputError(f"{path}: not a regular file (a table is one)")
    data = path.read_bytes()
    if kind == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        try:  # one thread: pyarrow 26's threaded read could leave a thread that aborted the interpreter
            # at exit ("terminate called without an active exception", exit code 134, in 1-4 runs of 12)
            records = pq.read_table(pa.BufferReader(data), use_threads=False).to_pylist()
        except Exception as exc:
            raise InvalidInputError(f"{path}: not a readable Parquet table: {exc}") from None
    else:
        try:
            reader = csv.DictReader(io.StringIO(data.decode("utf-8"), newline=""))
            rows = list(reader)
        except (UnicodeDecodeError, csv.Error) as exc:
            raise InvalidInputError(f"{path}: not a readable CSV table: {exc}") from None
        records = []
        for number, r in enumerate(rows, start=1):
            try:
                records.append({k: _csv_value(v, _TYPES.get(k, "str")) for k, v in r.items()})
            except (TypeError, ValueError) as exc:  # a row cut short (None), or a value that is not its type
                raise InvalidInputError(f"{path}: row {number} is not a transforms row (a truncated or edited "
                                        f"table): {exc}") from None
    missing = [c for c in COLUMNS if records and c not in records[0] and c not in _OPTIONAL]
    if missing:
        raise InvalidInputError(f"{path}: not a transforms table (no column {', '.join(missing)})")
    return [Transform.from_record(r) for r in records]


def _clean(value, name):
    if value is None and _TYPES[name] == "float" and name in ("center_x", "center_y", "center_z", "scale"):
        return math.nan
    return value
