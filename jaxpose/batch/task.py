"""One file's work in a batch: read, normalize, encode, as a pure function of its arguments.

:class:`NormalizeOptions` holds how each file is normalized (the arguments of
:func:`jaxpose.normalize_mesh`), validated once before any I/O; :func:`normalize_file` does one
file and returns its table columns and the encoded output without writing anything, so that it
can run in any worker process or on a Dask cluster and the caller alone writes.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import stat
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..config import OCSVM, OCSVM_ONLY, GridConfig, RobustConfig

__all__ = ["NormalizeOptions", "FileResult", "normalize_file", "one_line", "sha256_file", "input_key", "gltf_buffers", "warm_up", "recorded_settings"]


# --------------------------------------------------------------------------- options
@dataclasses.dataclass(frozen=True)
class NormalizeOptions:
    """How each file is normalized: the arguments of :func:`jaxpose.normalize_mesh`, validated once.

    Every value is checked when the object is made, before any file is read or anything compiled,
    by the same function as :func:`jaxpose.normalize_mesh` (:func:`jaxpose.mesh.check_arguments`):
    names (``method``, ``center``, ``scale``, ``sampling``, ``rotation``) against the known ones,
    ``gamma`` > 0, ``nu`` in [0, 1], ``count`` >= 4, ``seed`` >= 0, ``resolution`` only where
    an estimator or the frame reads one (the robust solid's, the OCSVM's grid) and within the memory
    budget of that grid; ``gamma``,
    ``nu``, ``count``, ``seed``, ``sampling`` other than their defaults only where the OCSVM is used
    (center, scale or rotation), as :func:`jaxpose.normalize_mesh` refuses them.

    Raises:
      InvalidInputError: a value out of range or a name not known, with the allowed ones.
    """

    method: str | None = None
    center: str | None = None
    scale: str | None = None
    gamma: float = OCSVM.gamma
    nu: float = OCSVM.nu
    count: int = OCSVM.count
    seed: int = OCSVM.seed
    sampling: str = OCSVM.sampling
    resolution: int | None = None
    rotation: bool | str = False
    strict: bool = False

    def __post_init__(self):
        from ..mesh import check_arguments

        check_arguments(**self.mesh_arguments())  # every value, the names, the grid's memory
        self._set(gamma=float(self.gamma), nu=float(self.nu), count=int(self.count), seed=int(self.seed),
                  resolution=None if self.resolution is None else int(self.resolution),
                  rotation=bool(self.rotation) if isinstance(self.rotation, (bool, np.bool_)) else self.rotation,
                  strict=bool(self.strict))

    def _set(self, **values):  # normalized values on a frozen instance, once, at construction
        for name, value in values.items():
            object.__setattr__(self, name, value)

    @property
    def rotation_method(self) -> str | None:
        """The rotation's frame method, or None without one."""
        from ..rotation.rotation import DEFAULT_ROTATION

        return (DEFAULT_ROTATION if self.rotation is True else self.rotation) or None

    @property
    def uses_jax(self) -> bool:
        """Whether normalizing a file with these options runs JAX: the ``ocsvm`` estimator (as the
        center, the scale or the rotation); every other estimator runs on the host in NumPy."""
        from ..pose.estimators import resolve

        return "ocsvm" in (*resolve(self.method, self.center, self.scale), self.rotation_method)

    @property
    def resolved_resolution(self) -> int | None:
        """The resolution the estimators use: the one given, else the default of the estimator that
        reads it, in the order of :func:`jaxpose.mesh.check_arguments`: the OCSVM's grid
        (:class:`jaxpose.config.GridConfig`) where the OCSVM is the center or the scale; else the robust
        solid's (:class:`jaxpose.config.RobustConfig`) for the ``robust_depth`` center, the
        ``robust_volume`` scale or the ``core`` and ``head`` frames; else the OCSVM's grid for the
        ``ocsvm`` frame; None where nothing reads one."""
        from ..pose.estimators import reads_resolution, resolve
        from ..rotation.rotation import SOLID_FRAMES

        if self.resolution is not None:
            return self.resolution
        c_name, s_name = resolve(self.method, self.center, self.scale)
        if "ocsvm" in (c_name, s_name):  # as jaxpose.mesh.check_arguments routes a resolution
            return GridConfig().resolution
        if reads_resolution(c_name, s_name) or self.rotation_method in SOLID_FRAMES:
            return RobustConfig().resolution
        if self.rotation_method == "ocsvm":
            return GridConfig().resolution
        return None

    def mesh_arguments(self) -> dict:
        """The keyword arguments of :func:`jaxpose.normalize_mesh` these options stand for (the
        OCSVM's own where it is used or where they differ from their defaults)."""
        ocsvm = {name: getattr(self, name) for name in OCSVM_ONLY
                 if self.uses_jax or _differs(getattr(self, name), getattr(OCSVM, name))}
        return dict(method=self.method, center=self.center, scale=self.scale, strict=self.strict,
                    resolution=self.resolution, rotation=self.rotation, **ocsvm)

    def columns(self) -> dict:
        """The table columns these options fill (method names and parameters)."""
        from ..pose.estimators import DEFAULT_METHOD, resolve

        c_name, s_name = resolve(self.method, self.center, self.scale)
        out = dict(method=self.method or DEFAULT_METHOD, center_method=c_name, scale_method=s_name,
                   gamma=self.gamma, nu=self.nu, count=self.count, seed=self.seed, sampling=self.sampling,
                   resolution=self.resolution)
        if self.rotation_method:
            out["rotation_method"] = self.rotation_method
        return out

    def fingerprint(self, file_format=None) -> str:
        """A string equal for equal options (and output format): the ``options`` column of a row."""
        return json.dumps({**dataclasses.asdict(self), "format": file_format}, sort_keys=True)

    def settings(self, file_format=None) -> dict:
        """What the outputs depend on, by name: what a rerun compares (:func:`recorded_settings`
        reads them back from a row's ``options``).

        ``method`` (the default's name for None), ``center`` and ``scale`` (the estimators), the
        OCSVM's ``gamma``, ``nu``, ``count``, ``seed``, ``sampling`` only where it runs (no other
        estimator reads them), ``resolution`` (:attr:`resolved_resolution`: a default written out
        is the default left out), ``rotation`` (the frame's method, or None), ``strict`` (True only
        where a closed-surface estimator reads it, :data:`jaxpose.pose.estimators.CLOSED_FORMS`), and
        ``format`` (the output format, None: each input's). Equal settings, equal outputs:
        ``NormalizeOptions()``, ``NormalizeOptions(method="robust")`` and
        ``NormalizeOptions(resolution=RobustConfig().resolution)`` have the same settings, not the
        same fingerprint (which keeps the options as given: the ``options`` column).
        """
        from ..pose.estimators import CLOSED_FORMS, DEFAULT_METHOD, resolve

        c_name, s_name = resolve(self.method, self.center, self.scale)
        out = {"method": self.method or DEFAULT_METHOD, "center": c_name, "scale": s_name}
        if self.uses_jax:
            out.update({name: getattr(self, name) for name in OCSVM_ONLY})
        strict = self.strict and bool(set(CLOSED_FORMS) & {c_name, s_name})
        out.update(resolution=self.resolved_resolution, rotation=self.rotation_method, strict=strict,
                   format=file_format)
        return out


def recorded_settings(fingerprint) -> dict | None:
    """:meth:`NormalizeOptions.settings` of a row's ``options`` (a :meth:`NormalizeOptions.fingerprint`),
    or None where the row has none (a record of a version before the column) or it does not read
    as this version's options."""
    pairs = _recorded_settings(fingerprint) if isinstance(fingerprint, str) else None
    return None if pairs is None else dict(pairs)


@functools.lru_cache(maxsize=256)  # a folder's rows share a few fingerprints; each is checked once
def _recorded_settings(fingerprint):
    from ..pose.estimators import CLOSED_FORMS, resolve

    try:
        values = json.loads(fingerprint)
        file_format = values.pop("format", None)
        if values.get("strict") is True:  # an earlier version took strict=True where nothing reads it (the
            # robust default): its outputs are those of strict=False, which this version's settings record
            if not set(CLOSED_FORMS) & set(resolve(values.get("method"), values.get("center"), values.get("scale"))):
                values["strict"] = False
        return tuple(NormalizeOptions(**values).settings(file_format).items())
    except Exception:  # not JSON, unknown fields, values this version refuses
        return None


def _differs(value, default) -> bool:
    """Whether an option's value is not its default (a value that cannot be compared is)."""
    try:
        return bool(value != default)
    except (TypeError, ValueError):  # an array: its check says what is wrong
        return True


# --------------------------------------------------------------------------- one file
class FileResult(NamedTuple):
    """What :func:`normalize_file` returns.

    Attributes:
      record: table columns known to the worker (``status``, ``error``, ``kind``, ``vertices``,
        ``faces``, ``center_x/_y/_z``, ``scale``, ``valid``, ``converged``, rotation columns,
        ``seconds``, ``worker``, ``worker_peak_mb``, ``version``, and for a path ``input_size``,
        ``input_mtime_ns``, ``input_sha256``, ``input_stat``: :func:`input_key`) and ``matrix``
        (4 x 4 nested lists, or None).
      data: the encoded normalized file, or None when the input failed.
    """

    record: dict
    data: bytes | None


def normalize_file(source, options=None, file_type=None, check="mtime") -> FileResult:
    """Read one mesh or point cloud, normalize it and encode the result; a pure function.

    Nothing is written: the caller decides where the bytes go. Errors of the input (unreadable,
    empty, NaN coordinates, a point cloud for a triangles-only format, no valid pose, a file that
    changed while it was read) come back as ``record["status"] == "failed"`` with a one-line
    ``record["error"]``. The input's size and modification time (and SHA-256) are those of the
    bytes read: taken just before reading and checked unchanged just after.

    Args:
      source: a path (anything :func:`jaxpose.mesh.load` reads) or a Trimesh / PointCloud.
      options: :class:`NormalizeOptions` (default: the defaults).
      file_type: output format (:data:`jaxpose.mesh.OUTPUT_FORMATS`); default the source's suffix
        (GLB for a ``.gltf``, which jaxpose reads but does not write; give it for a geometry object).
      check: ``"hash"`` also records the SHA-256 of a regular file's bytes (``input_sha256``).

    Returns:
      :class:`FileResult`.
    """
    import socket

    start = time.perf_counter()
    options = NormalizeOptions() if options is None else options
    record = {"status": "failed", "error": "", "kind": "", "vertices": 0, "faces": 0, "matrix": None}
    data = None
    try:
        from .. import mesh

        from ..io.remote import is_url

        if is_url(source) and not source.lower().startswith("file://"):
            geometry = _load_remote(source, check, record)
        else:
            before = _input_stat(source, check) if isinstance(source, (str, os.PathLike)) else {}
            record.update({k: v for k, v in before.items() if k != "input_identity"})
            geometry = mesh.read(source) if isinstance(source, (str, os.PathLike)) else mesh.load(source)
            if before.get("input_identity") is not None:
                _check_unchanged(source, before)
        record.update(kind="mesh" if hasattr(geometry, "faces") else "points",
                      vertices=len(geometry.vertices), faces=len(getattr(geometry, "faces", ())))
        ext = _output_format(mesh, file_type, source, geometry)
        normalized, pose = mesh.normalize_mesh(geometry, **options.mesh_arguments())
        record.update(_pose_columns(pose, mesh.pose_matrix(pose)))
        data = mesh.encode(normalized, ext)
        record.update(status="ok")
    except Exception as exc:  # every failure of one input is that input's record, not the run's end
        record.update(error=one_line(exc))
    from .. import __version__

    record.update(seconds=time.perf_counter() - start, worker=f"{socket.gethostname()}:{os.getpid()}",
                  worker_peak_mb=_peak_mb(), version=__version__)
    return FileResult(record, data)


def _output_format(mesh, file_type, source, geometry):
    """:func:`jaxpose.mesh.output_format` of the output format (`file_type`, else the source's
    suffix) for `geometry`; its refusal names that format and where it came from, not a file name
    (the output's path is the caller's)."""
    from .._validate import InvalidInputError

    own = file_type is None
    kind = (Path(str(source)).suffix.lstrip(".") if own else file_type).lower()
    if own:  # a format read but not written (.gltf) is written as another (.glb): the output's name says so
        from .inputs import WRITTEN_AS

        kind = WRITTEN_AS.get("." + kind, "." + kind)[1:]
    placeholder = f"output.{kind}"
    try:
        return mesh.output_format(placeholder, geometry)
    except InvalidInputError as exc:
        whose = "the input's own, kept without --format" if own else "--format / file_type"
        raise InvalidInputError(str(exc).replace(f"{placeholder}: ", f"output format {kind or '(none)'} ({whose}): ", 1)
                                ) from None


def _load_remote(url, check, record):
    """Read a remote file (:mod:`jaxpose.io.remote`): its bytes through a local temporary file of
    the same suffix (the readers take paths); size, time and SHA-256 of those bytes in `record`."""
    import tempfile

    from .. import mesh
    from .._validate import InvalidInputError, JaxposeError
    from ..io.remote import location, modified_ns

    path = location(url)
    try:
        info = path.info()
    except FileNotFoundError:
        raise InvalidInputError(f"no such file: {url}") from None
    data = path.read_bytes()
    record.update(input_size=len(data), input_mtime_ns=modified_ns(info),
                  input_sha256=hashlib.sha256(data).hexdigest() if check == "hash" else "")
    after = path.info()
    if (after.get("size"), modified_ns(after)) != (info.get("size"), modified_ns(info)) or len(data) != info.get("size"):
        raise InvalidInputError(f"{url}: changed while it was read; run again to read it whole")
    with tempfile.TemporaryDirectory(prefix="jaxpose-") as folder:
        local = Path(folder) / ("input" + path.suffix.lower())
        local.write_bytes(data)
        try:
            return mesh.read(local)
        except JaxposeError as exc:  # its message names the temporary file: name the URL
            if local.suffix == ".gltf" and "it refers to" in str(exc):  # (the temporary folder holds the .gltf alone)
                raise type(exc)(f"{url}: a remote .gltf is read alone, without the buffer files beside it that it "
                                "refers to; convert it to .glb (one file), or copy its folder to a local one") from None
            raise type(exc)(str(exc).replace(str(local), url)) from None


def warm_up(options=None) -> None:
    """Import what :func:`normalize_file` needs for `options` (:class:`NormalizeOptions`; default
    the defaults): a new worker process runs this before its first input, so that its start-up
    does not count against that input's time limit. The readers and the estimators always (not
    trimesh: a plain OFF, PLY or OBJ file goes through as arrays, :func:`jaxpose.io.mesh.read`);
    JAX only for options that use it (:attr:`NormalizeOptions.uses_jax`: the robust default and the
    classical estimators of a file run on the host without it). A first compilation still counts."""
    from .. import mesh  # noqa: F401

    if options is not None and options.uses_jax:
        import jax.numpy  # noqa: F401


def _input_stat(path, check):
    """The input's table columns from ``os.stat`` (nothing for a file that cannot be stat'ed: the
    read says why), with its SHA-256 for a regular file when `check` is ``"hash"``: those of
    :func:`input_key`, and ``input_identity``, for each of its files in that order, ``[device,
    inode number, status-change time (ns)]``, to see a file replaced or rewritten while it is read
    (even keeping its size and modification time); not recorded, not compared by a rerun."""
    out, files = _key_files(path, check)
    if files:
        out["input_identity"] = [[i.st_dev, i.st_ino, i.st_ctime_ns] for _, i in files]
    return out


def input_key(path, check) -> dict:
    """What a rerun compares of a local input (``input_size``, ``input_mtime_ns``, ``input_sha256``,
    ``input_stat``): those of the file; for a ``.gltf``, of the file and the buffer files it names
    (:func:`gltf_buffers`), which hold its geometry: their sizes summed, the latest modification
    time, and the SHA-256 of each file's bytes after its size (the file's own SHA-256 where it names
    none); ``input_stat``, for each file in that order, ``[size, modification time (ns)]``, so that
    a buffer replaced by an older one of the same size differs. Not its inode number or
    status-change time: moving, restoring or ``chmod``-ing a file, a new hard link or another
    mount change those and not the bytes. A file replaced by one of the same size and the same
    modification time is not seen by these (``"hash"``'s SHA-256 sees it). None (size, time, stat)
    for a path that is not a regular file or cannot be stat'ed (never opened here: a FIFO would
    block; its read says why).

    Raises:
      OSError: the file (or a buffer) could not be read for its SHA-256.
    """
    return _key_files(path, check)[0]


def _key_files(path, check):
    """:func:`input_key`'s dict, and the files it covers: ``(path, os.stat result)`` each, in
    order (none where the key is None)."""
    out = {"input_size": None, "input_mtime_ns": None, "input_sha256": "", "input_stat": None}
    try:
        info = os.stat(path)
    except OSError:
        return out, []
    if not stat.S_ISREG(info.st_mode):  # a FIFO or device: no size, nothing to compare afterwards
        return out, []
    files = [(path, info)]
    for buffer in gltf_buffers(path):
        try:
            buffer_info = os.stat(buffer)
        except OSError:  # missing: the read fails, naming it
            continue
        if stat.S_ISREG(buffer_info.st_mode):  # a FIFO is never opened here (hashing it would block)
            files.append((buffer, buffer_info))
    out.update(input_size=sum(i.st_size for _, i in files), input_mtime_ns=max(i.st_mtime_ns for _, i in files),
               input_stat=[[i.st_size, i.st_mtime_ns] for _, i in files])
    if check == "hash":
        if len(files) == 1:
            out["input_sha256"] = sha256_file(path)
        else:
            digest = hashlib.sha256()
            for name, _ in files:
                digest.update(b"%d\0%s" % (os.stat(name).st_size, sha256_file(name).encode("ascii")))
            out["input_sha256"] = digest.hexdigest()
    return out, files


def gltf_buffers(path) -> list:
    """The local files a ``.gltf`` names as its buffers (URIs relative to its folder, not ``data:``
    ones), in its order, each found as trimesh's reader finds it (:func:`_buffer_file`; a name
    found nowhere is left out: the read fails, naming it); none for another file, or a .gltf that
    does not parse or whose ``buffers`` is not a list of objects (its read says why)."""
    path = Path(path)
    if path.suffix.lower() != ".gltf":
        return []
    try:
        with open(path, "rb") as handle:
            tree = json.loads(handle.read())
        buffers = tree.get("buffers") or []
        if not (isinstance(buffers, list) and all(isinstance(b, dict) for b in buffers)):
            return []
        uris = [b["uri"] for b in buffers if isinstance(b.get("uri"), str)]
    except (OSError, ValueError, AttributeError, TypeError):
        return []
    found = (_buffer_file(path.parent, uri) for uri in uris if ":" not in uri.split("/")[0])
    return [file for file in found if file is not None]


def _buffer_file(folder, name):
    """The file trimesh's reader opens for a buffer name of a .gltf in `folder`, or None: the
    reader's own rule (:func:`jaxpose.io.mesh.gltf_file`)."""
    from ..io.mesh import gltf_file

    return gltf_file(folder, name)


def _check_unchanged(path, before):
    from .._validate import InvalidInputError

    try:
        os.stat(path)
        now = _input_stat(path, "mtime")
    except OSError as exc:
        raise InvalidInputError(f"{path}: removed while it was read ({exc.strerror})") from None
    fields = ("input_size", "input_mtime_ns", "input_stat", "input_identity")  # no size: not a regular file now
    if now["input_size"] is None or any(now.get(f) != before.get(f) for f in fields):
        files = [[identity[:2] for identity in key.get("input_identity") or ()] for key in (before, now)]
        if now["input_size"] is None:
            size = f"{before['input_size']} bytes -> not a regular file"
        elif now["input_size"] != before["input_size"]:
            size = f"{before['input_size']} -> {now['input_size']} bytes"
        elif any(now.get(f) != before.get(f) for f in ("input_mtime_ns", "input_stat")):
            size = f"{now['input_size']} bytes, its modification time moved"
        elif files[0] != files[1]:
            size = f"{now['input_size']} bytes, replaced by another file"
        else:  # the same files, sizes and times: only the status-change time moved
            raise InvalidInputError(f"{path}: its status changed while it was read: rewritten keeping its size and "
                                    "time, or its permissions or links changed; run again to read it whole")
        raise InvalidInputError(f"{path}: changed while it was read (size {size}); run again to read it whole")


def sha256_file(path) -> str:
    """The SHA-256 of a file's bytes, hex."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _pose_columns(pose, matrix):
    import numpy as np

    center = np.asarray(pose.center, dtype=np.float64).reshape(3)
    out = dict(center_x=float(center[0]), center_y=float(center[1]), center_z=float(center[2]),
               scale=float(np.asarray(pose.scale, dtype=np.float64)), valid=bool(np.all(pose.valid)),
               converged=bool(np.all(pose.converged)), matrix=matrix.tolist())
    if getattr(pose, "rotation", None) is not None:
        rotation = np.asarray(pose.rotation, dtype=np.float64).reshape(3, 3)
        out.update({f"r{i}{j}": float(rotation[i, j]) for i in range(3) for j in range(3)})
        out["ambiguity"] = float(np.asarray(pose.ambiguity, dtype=np.float64))
    return out


def one_line(exc) -> str:
    """An exception as one line: its message (a JaxposeError's), else ``Type: message``."""
    from .._validate import JaxposeError

    text = " ".join(str(exc).split())
    return text if isinstance(exc, JaxposeError) and text else f"{type(exc).__name__}: {text}".rstrip(": ")


def _peak_mb():
    try:
        import resource
    except ImportError:  # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 2**20 if os.uname().sysname == "Darwin" else peak / 2**10
