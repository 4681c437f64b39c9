"""Mesh and point-cloud files in and out: load, encode, export, and the example shape.

The only module that uses trimesh for file I/O. Loading never modifies the input
file; exporting is atomic (temporary file in the target directory, then
``os.replace``) and refuses to overwrite unless ``force=True``.

trimesh is imported where it is used (:func:`_trimesh`): a file that the fast readers read and
nothing else of trimesh needs (:func:`read`: a :class:`~jaxpose.geometry.Surface`) is read,
normalized and written (OFF, PLY) without it, so that a command's start-up does not import it.
"""
from __future__ import annotations

import io
import os
import sys
from pathlib import Path

import numpy as np

from . import formats, readers, writers
from .._validate import InvalidInputError, check_concrete, check_points
from ..geometry import Surface, is_pair
from .atomic import write_atomic

__all__ = [
    "load",
    "read",
    "read_stored",
    "MESH_FORMATS",
    "POINT_FORMATS",
    "OUTPUT_FORMATS",
    "output_format",
    "encode",
    "export",
    "write_atomic",
    "example_shape",
]


# --------------------------------------------------------------------------- load
def load(path_or_mesh):
    """Read a mesh or point cloud from anything trimesh reads (OBJ, PLY, OFF, STL, GLB, ...).

    A Scene is concatenated into one geometry; geometry without faces comes back as
    a :class:`trimesh.PointCloud`. Trimesh/PointCloud/Scene objects and ``(n, 3)``
    arrays (NumPy, JAX, nested lists) are accepted as they are (arrays become point clouds). A named pipe (FIFO, or a shell's
    ``<(command)``) is read to the end of its stream; one that delivers nothing for
    :data:`PIPE_WAIT_S` seconds (no writer) fails rather than waiting for ever.

    Returns
    -------
    geometry : trimesh.Trimesh | trimesh.PointCloud
    """
    if isinstance(path_or_mesh, (str, os.PathLike)):
        geometry = read(path_or_mesh)
        return _trimesh_of(geometry) if isinstance(geometry, Surface) else geometry
    return _checked(path_or_mesh, "input")


def read(path):
    """What :func:`load` gives for a file, without trimesh where it is not needed: a
    :class:`~jaxpose.geometry.Surface` of the same vertices and faces for a mesh that the fast
    readers read and that holds nothing else trimesh would keep (colors, UV, an STL's names), else
    :func:`load`'s Trimesh or PointCloud.

    Raises:
      InvalidInputError: as :func:`load`.
    """
    geometry = _read(Path(path))
    if isinstance(geometry, readers.Loaded):
        return _from_loaded(geometry, str(path))
    return _checked(geometry, str(path))


def _trimesh():
    import trimesh

    return trimesh


def _is(geometry, name):
    """isinstance(geometry, trimesh.<name>), without importing trimesh (nothing is a trimesh object
    before it is imported)."""
    module = sys.modules.get("trimesh")
    return module is not None and isinstance(geometry, getattr(module, name))


def _trimesh_of(surface):
    return _trimesh().Trimesh(vertices=surface.vertices, faces=surface.faces, process=False)


def _checked(geometry, source):
    """A geometry object or array as :func:`load` returns it (a Surface kept as a Surface)."""
    if isinstance(geometry, Surface):
        check_concrete(source, *geometry)
        vertices, faces = (np.asarray(a) for a in geometry)
        check_points(vertices, name=f"vertices of {source}", min_points=1)
        kind = faces.dtype.kind  # indices: integers (whole floats taken; 7.5 or a bool is no index)
        if kind not in "iu" and not (kind == "f" and np.all(np.mod(faces, 1) == 0)):
            raise InvalidInputError(f"{source}: faces must be (m >= 1, 3) indices of its vertices (integers), got "
                                    f"{faces.dtype}{' with fractions' if kind == 'f' else ''}")
        if faces.ndim != 2 or faces.shape[1] != 3 or not len(faces) or faces.min() < 0 or faces.max() >= len(vertices):
            raise InvalidInputError(f"{source}: faces must be (m >= 1, 3) indices of its vertices")
        return geometry
    trimesh = _trimesh()
    if isinstance(geometry, trimesh.Scene):
        geometry = _flatten(geometry, source)
    if not isinstance(geometry, (trimesh.Trimesh, trimesh.PointCloud)):
        check_concrete(source, geometry)  # np.asarray would raise JAX's TracerArrayConversionError
        # arrays: NumPy's, lists, and any array NumPy converts (a JAX array)
        if hasattr(geometry, "vertices") or isinstance(geometry, (np.ndarray, list, tuple)) or (
                hasattr(geometry, "__array__") and not isinstance(geometry, (str, bytes))):
            points = getattr(geometry, "vertices", geometry)
            if is_pair(points):
                raise InvalidInputError(f"{source}: a (vertices, faces) pair: pass jaxpose.geometry.Surface(vertices, "
                                        "faces) for a mesh (an array of points is a point cloud)")
            check_points(points, name=f"points of {source}", min_points=1)
            geometry = trimesh.PointCloud(np.asarray(points, dtype=np.float64))
        else:
            raise InvalidInputError(f"{source}: cannot use a {type(geometry).__name__} as a mesh")
    if len(geometry.vertices) == 0:
        raise InvalidInputError(f"{source}: empty geometry (no vertices)")
    if np.shape(geometry.vertices)[1:] != (3,):
        raise InvalidInputError(f"{source}: vertices must have 3 coordinates, got shape {np.shape(geometry.vertices)}")
    if not np.all(np.isfinite(geometry.vertices)):
        raise InvalidInputError(f"{source}: vertices with NaN or inf coordinates")
    if isinstance(geometry, trimesh.Trimesh) and len(geometry.faces) == 0:
        geometry = trimesh.PointCloud(np.asarray(geometry.vertices))
    if isinstance(geometry, trimesh.Trimesh):
        faces = np.asarray(geometry.faces)
        if faces.min() < 0 or faces.max() >= len(geometry.vertices):
            raise InvalidInputError(f"{source}: faces must be (m >= 1, 3) indices of its vertices (a face references "
                                    f"vertex {int(faces.max() if faces.max() >= len(geometry.vertices) else faces.min())} "
                                    f"of {len(geometry.vertices)})")
    if source != "input" and isinstance(geometry, trimesh.Trimesh):
        _merge_vertices(geometry, source)  # STL and friends store each triangle's corners apart
    return geometry


def _merge_vertices(geometry, source="input"):
    """trimesh's ``merge_vertices`` (an absolute tolerance, 1e-8), decided near the origin: far from
    it, rounding every coordinate to 1e-8 overflows and merges distinct vertices. The merge runs on
    a copy moved by an anchor vertex (:func:`jaxpose.host.anchor`); the vertices kept are then
    taken from the input as they are, so loading changes no coordinate, not even by rounding. A
    mesh reaching farther than :data:`MERGE_REACH` from that vertex is refused (trimesh's int64
    keys overflow there and merge distinct vertices). The file's vertex normals never keep vertices
    apart (``merge_norm=True``: moving the vertices drops them from trimesh's cache, but not a move
    by an anchor at the origin, the same values)."""
    from ..host import anchor

    original = np.asarray(geometry.vertices, np.float64)
    faces = np.asarray(geometry.faces, np.int64)
    moved = original - anchor(original)
    reach = float(np.max(np.abs(moved)))
    if reach >= MERGE_REACH:
        raise InvalidInputError(
            f"{source}: the mesh reaches {reach:.3g} from its middle vertex; beyond {MERGE_REACH:.3g} trimesh's "
            "vertex merge (coordinates in steps of 1e-8 as int64) merges distinct vertices: rescale it")
    geometry.vertices = moved
    geometry.merge_vertices(merge_norm=True)
    inverse = np.full(len(original), -1, np.int64)  # original vertex -> merged vertex
    inverse[faces.ravel()] = np.asarray(geometry.faces, np.int64).ravel()
    referenced = np.nonzero(inverse >= 0)[0]
    merged, first = np.unique(inverse[referenced], return_index=True)
    if not np.array_equal(merged, np.arange(len(geometry.vertices))):  # not the documented merge
        raise InvalidInputError("could not merge the mesh's duplicate vertices")
    geometry.vertices = original[referenced[first]]


_MERGE_DIGITS = 8  # trimesh's tol.merge, 1e-8
MERGE_REACH = 2.0**63 / 10**_MERGE_DIGITS  # 9.2e10: farther from the anchor, trimesh's int64 keys overflow
_MIX = (np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB))


def _hash_keys(keys):
    """A 64-bit hash of each row of 64-bit keys (n, 3), of their bits: splitmix64's finalizer,
    chained over the columns (a shape's mirrored vertices, (a, b, c) and (-a, -b, c), hash apart).
    (n,) uint64."""
    def mix(x):
        x = x ^ (x >> np.uint64(30))
        x = x * _MIX[0]
        x = x ^ (x >> np.uint64(27))
        x = x * _MIX[1]
        return x ^ (x >> np.uint64(31))

    columns = keys.view(np.uint64)
    with np.errstate(over="ignore"):
        hashed = mix(columns[:, 0].copy())
        for column in range(1, columns.shape[1]):
            hashed = mix(hashed + columns[:, column])
    return hashed


def _merged(vertices, faces):
    """:func:`_merge_vertices` on arrays: (keep, inverse) such that ``vertices[keep]`` and
    ``inverse[faces]`` are the merged mesh, or None where it cannot tell (then trimesh merges).

    trimesh's keys (coordinates moved by the anchor, times 1e8, rounded; kept as float64, equal
    where trimesh's int64 keys are equal and still exact beyond :data:`MERGE_REACH`, where int64
    overflows), its order (the referenced vertices' first occurrences, in file order; unreferenced
    ones dropped); the duplicate keys found by sorting a hash of each key and comparing the keys it
    groups. keep : (k,) int64, inverse : (n,) int64."""
    from ..host import anchor

    referenced = np.zeros(len(vertices), bool)
    referenced[faces] = True
    used = np.nonzero(referenced)[0]
    keys = ((vertices[used] - anchor(vertices)) * (10**_MERGE_DIGITS)).round() + 0.0  # + 0.0: -0.0 is 0.0
    hashed = _hash_keys(keys)
    inverse = np.zeros(len(vertices), np.int64)
    ranked = np.sort(hashed)
    if np.all(ranked[1:] != ranked[:-1]):  # no duplicates (the usual file: a sort says so sooner)
        inverse[used] = np.arange(len(used))
        return used, inverse
    order = np.argsort(hashed, kind="stable")  # equal hashes: first occurrence first
    starts = np.ones(len(order), bool)
    starts[1:] = hashed[order[1:]] != hashed[order[:-1]]
    if np.any(~starts[1:] & np.any(keys[order[1:]] != keys[order[:-1]], axis=1)):
        return None  # a hash shared by different keys
    first = order[starts]
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))  # groups in order of first occurrence
    group = np.empty(len(order), np.int64)
    group[order] = np.cumsum(starts) - 1
    inverse[used] = rank[group]
    return used[np.sort(first)], inverse


def _from_loaded(loaded, source):
    """What :func:`read` makes of a fast reader's mesh, on arrays: its checks and vertex merge, then
    a Surface, or one ``trimesh.Trimesh`` where the file holds more (colors, UV, names). Normals
    from the file are dropped, as the merge drops them on trimesh's path (moving the vertices
    clears trimesh's cache)."""
    if not np.all(np.isfinite(loaded.vertices)):
        raise InvalidInputError(f"{source}: vertices with NaN or inf coordinates")
    extras = {k: v for k, v in loaded.extras.items() if k not in ("vertex_normals", "face_normals")}
    merged = None if "visual" in extras else _merged(loaded.vertices, loaded.faces)  # UV: trimesh's merge
    if merged is None:
        geometry = _trimesh().Trimesh(**loaded.kwargs(), process=False)
        _merge_vertices(geometry, source)
        return geometry
    keep, inverse = merged
    if not extras:
        return Surface(loaded.vertices[keep], inverse[loaded.faces])
    if "vertex_colors" in extras:
        extras["vertex_colors"] = extras["vertex_colors"][keep]
    return _trimesh().Trimesh(vertices=loaded.vertices[keep], faces=inverse[loaded.faces], process=False, **extras)


def check_input(path):
    """Refuse, without reading it, a `path` that :func:`load` cannot open: missing, not a file (a
    folder; a named pipe is a file here), or in a folder this user may not search; the words
    :func:`load` uses (a command names a missing input before its other arguments' problems).

    Raises:
      InvalidInputError: naming `path` ("no such file: PATH", "not a file: PATH").
    """
    path = Path(path)
    try:  # (pathlib raises PermissionError for a file in a folder this user may not search)
        if not path.exists():
            raise InvalidInputError(f"no such file: {path}")
        if not (path.is_file() or path.is_fifo()):  # a named pipe delivers a stream: read it
            raise InvalidInputError(f"not a file: {path}")
    except OSError as exc:
        raise InvalidInputError(f"{path}: cannot read: {exc.strerror}") from None


def _read(path):
    check_input(path)
    ext = path.suffix.lower().lstrip(".")
    if ext not in readers.READERS:  # (trimesh's formats: its list, and names of two suffixes)
        known = set(_trimesh().available_formats())
        ext = "".join(path.suffixes[-2:]).lower().lstrip(".") if path.suffix else ""
        if ext not in known:
            ext = path.suffix.lower().lstrip(".")
        if ext not in known:
            raise InvalidInputError(f"{path}: unsupported format {path.suffix or '(no extension)'!r}; "
                                    f"readable: {', '.join(sorted(known))}")
    try:
        data = _read_pipe(path) if path.is_fifo() else path.read_bytes()  # read-only: never touched
    except OSError as exc:
        raise InvalidInputError(f"{path}: cannot read: {exc.strerror}") from None
    found = formats.sniff_format(data)
    if found is not None and found != ext and ext in ("ply", "glb", "stl", "off", "obj", "xyz"):
        raise InvalidInputError(f"{path}: the content is {found.upper()}, not {ext.upper()}: "
                                f"rename it to .{found} (the extension chooses the reader)")
    if ext == "stl" and (problem := formats.binary_stl_mismatch(data)):  # not "empty geometry ... not STL"
        raise InvalidInputError(f"{path}: {problem}")
    if ext in formats.TEXT_FORMATS or (ext == "stl" and found == "stl" and not formats.binary_stl(data)):
        data = formats.as_text(data, f"{path}", ext)
    if ext in ("off", "obj", "xyz"):  # what trimesh misreads: an OFF's late comments, an OBJ's tabs, an XYZ's commas
        try:
            data = formats.as_read(data, ext)
        except InvalidInputError as exc:
            raise InvalidInputError(f"{path}: {exc}") from None
    if ext in readers.READERS:
        try:
            return readers.read(data, ext)
        except readers.Unsupported:  # trimesh reads it
            pass
        except InvalidInputError as exc:  # broken where trimesh would read part of it
            raise InvalidInputError(f"{path}: {exc}") from None
    if not (data.strip() if ext in formats.TEXT_FORMATS else data):  # 0 bytes, or a text's white space and comments:
        raise _empty(path, ext)  # each reader's own words else ("not enough columns", "Not a ply file!", ...)
    trimesh = _trimesh()
    values = data.strip() if ext == "xyz" else b""
    one_point = bool(values) and b"\n" not in values  # one line of values (comments cut): trimesh counts its
    if one_point:  # columns without the last character (no line end after strip()): "1 2 3" "not enough
        data = values + b"\n" + values  # columns"; read twice, keep one
    # a .gltf names its buffers (and images) as files beside it: read them from its folder (the
    # bytes alone leave trimesh nothing to read them with: "'NoneType' object is not subscriptable")
    resolver = _gltf_resolver(path) if ext == "gltf" else None
    try:
        geometry = trimesh.load(io.BytesIO(data), file_type=ext, process=False, resolver=resolver)
    except _NotRegular as exc:  # a FIFO beside it: never opened (a plain open waited for a writer)
        raise InvalidInputError(str(exc)) from None
    except FileNotFoundError as exc:  # only the resolver opens files: one the .gltf refers to is missing
        if (problem := _not_json(data)) is not None:  # trimesh then asks for a file of its own name ("model.gltf")
            raise InvalidInputError(f"{path}: cannot read GLTF file: not a JSON text ({problem}): a truncated or "
                                    "malformed file (a .gltf is JSON; a binary glTF is .glb)") from None
        raise InvalidInputError(f"{path}: cannot read {ext.upper()} file: it refers to {exc}, which is not in its "
                                f"folder {path.parent} (a .gltf's buffers are files beside it; a .glb holds them)") from None
    except Exception as exc:  # every reader has its own errors for corrupt files
        if ext == "obj" or ext == "ply":  # the fast reader's words: a texture coordinate or a face beyond its
            try:  # count, a vertex line without its coordinates
                if ext == "obj":
                    readers.obj.check_texture_references(data)
                if (ext == "obj" and isinstance(exc, IndexError)) or ext == "ply":
                    (readers.obj.check_vertex_references if ext == "obj" else readers.ply.check_vertex_lines)(data)
            except InvalidInputError as named:
                raise InvalidInputError(f"{path}: {named}") from None
        detail = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        if ext == "off" and b"OFF" not in data:  # (trimesh's words: "not enough values to unpack (expected 3, got 1)")
            detail = "no OFF header (an OFF file starts with the line 'OFF'): not an OFF file, or a malformed one"
        if isinstance(exc, ImportError):  # trimesh's optional modules, wanted for a content it could not parse
            detail = (f"the content is not {ext.upper()} as jaxpose and trimesh read it (trimesh wanted its optional "
                      f"module {exc.name!r} to try further)")
        raise InvalidInputError(f"{path}: cannot read {ext.upper()} file: {detail}") from None
    if resolver is not None and resolver.refused is not None:  # an image trimesh skipped (the read went on)
        raise InvalidInputError(str(resolver.refused))
    if one_point and len(geometry.vertices) == 2:
        colors = np.asarray(geometry.colors)
        geometry = trimesh.PointCloud(geometry.vertices[:1], colors=colors[:1] if len(colors) else None)
    if not _has_vertices(geometry):
        raise _empty(path, ext)
    if ext == "obj" and _lost_uv(data, geometry):
        try:  # (the fast reader's check: trimesh drops every UV of a file with a reference out of range)
            readers.obj.check_texture_references(data)
        except InvalidInputError as exc:
            raise InvalidInputError(f"{path}: {exc}") from None
    return geometry


def _not_json(data):
    """Why the bytes `data` are not a JSON text (a .gltf's), or None where they are one."""
    import json

    try:
        json.loads(data)
    except ValueError as exc:  # (UnicodeDecodeError too)
        return str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return None


def gltf_file(folder, name):
    """The file jaxpose's reader opens for a buffer (or image) name of a .gltf in `folder`, or None:
    the name as it is, without its leading ``/``, its last part; each taken literally (no
    %-decoding) in the folder, the first that exists and does not lead out of the folder (the rule
    of trimesh 5's ``FilePathResolver.get``; the reader applies it on every trimesh version)."""
    parent = Path(folder).resolve()
    for candidate in (name.strip(), name.strip().lstrip("/"), os.path.split(name)[-1]):
        file = (parent / candidate.strip()).resolve()
        if (file == parent or parent in file.parents) and file.exists():
            return file
    return None


class _NotRegular(Exception):
    """A file a .gltf names that is not a regular file (its message names both)."""


def _gltf_resolver(path):
    """A resolver of the files beside the .gltf `path` for trimesh's reader: :func:`gltf_file`'s
    file, its bytes (FileNotFoundError naming the name where there is none), refusing
    (:class:`_NotRegular`) one that is not a regular file before it is opened: a FIFO's ``open``
    waits for a writer, for ever when none comes (a folder, a device: named as well). It reads the
    file itself (trimesh's own ``get`` follows another rule on each major version: 4's opens
    ``../name``, a file out of the folder). An image (a texture) is refused by the same rule, but
    trimesh's reader skips an image it cannot get and reads on: the refusal is kept in the
    resolver's ``refused`` (the first one; None while there is none), for the caller to raise
    once trimesh returns, worded for an image. A missing or unreadable image that is a regular
    file is left to trimesh (it skips it)."""
    import stat

    def refuse(name, file, mode, files="buffer files"):
        kind = next((kind for test, kind in ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISDIR, "a folder"),
                                             (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
                                             (stat.S_ISBLK, "a block device")) if test(mode)), "not a file")
        return _NotRegular(f"{path}: the file {name!r} it refers to ({file}) is {kind}, not a regular "
                           f"file: a .gltf's {files} are read as regular files only (it was not opened)")

    class Resolver(_trimesh().resolvers.FilePathResolver):
        refused = None

        def get(self, name):
            file = gltf_file(self.parent, name)
            if file is None:
                raise FileNotFoundError(name)
            mode = os.stat(file).st_mode
            if not stat.S_ISREG(mode):
                raise self._refuse(name, file, mode)
            fd = os.open(file, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))  # replaced by a FIFO since: not held
            with os.fdopen(fd, "rb") as handle:
                mode = os.fstat(handle.fileno()).st_mode
                if not stat.S_ISREG(mode):
                    raise self._refuse(name, file, mode)
                return handle.read()

        def _refuse(self, name, file, mode):
            if self.refused is None:  # raised after trimesh returns only where it skipped it: an image
                self.refused = refuse(name, file, mode, files="image files")
            return refuse(name, file, mode)

    return Resolver(str(path))


def _empty(path, ext):
    """The error of a file that holds no vertices (an empty file, one of comments only, a content
    the reader found nothing in)."""
    return InvalidInputError(f"{path}: empty geometry: no vertices read as {ext.upper()} (the file is empty, "
                             f"or its content is not {ext.upper()})")


def _lost_uv(data, geometry):
    """Whether an OBJ file's text `data` has ``vt`` lines and a mesh trimesh read of it holds no UV
    coordinates (what trimesh's loader leaves where a face references a texture coordinate that is
    not there): only then is :func:`jaxpose.io.readers.obj.check_texture_references` run, so a
    file whose UV trimesh kept is not scanned again."""
    if not (data.startswith((b"vt ", b"vt\t")) or b"\nvt " in data or b"\nvt\t" in data):
        return False
    parts = geometry.geometry.values() if _is(geometry, "Scene") else [geometry]
    return any(getattr(getattr(part, "visual", None), "uv", None) is None for part in parts
               if _is(part, "Trimesh"))


def read_stored(path):
    """A file's geometry as :func:`read` reads it (the same checks, text decoding and fixes of the
    text: :func:`jaxpose.io.formats.as_text`, :func:`jaxpose.io.formats.as_read`, an OBJ's texture
    references) before anything is merged or checked beyond reading: the fast readers'
    :class:`jaxpose.io.readers.Loaded`, else trimesh's geometry as loaded (``process=False``; a
    Scene, a Trimesh or a PointCloud).

    Raises:
      InvalidInputError: a missing, unreadable or unsupported file, naming it.
    """
    return _read(Path(path))


PIPE_WAIT_S = 60.0
"""Seconds a named pipe (FIFO) may stay silent before its read fails: the wait for a writer to
open it, and each wait for more bytes once one has."""


def _read_pipe(path):
    """The bytes of a named pipe, to the end of its stream, without ever blocking for good.

    A plain ``open`` of a FIFO for reading waits for a writer, for ever when none comes; it is
    opened non-blocking instead and each wait for bytes (the first included) is bounded by
    :data:`PIPE_WAIT_S`. The stream ends when its last writer closes it.

    Raises:
      InvalidInputError: nothing came for :data:`PIPE_WAIT_S` seconds (naming the file).
    """
    import select

    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    chunks = []
    try:
        while True:
            # no writer yet: not readable (Linux reports the end of a stream only after a writer
            # has come and gone); bytes or that end: readable
            if not select.select([fd], [], [], PIPE_WAIT_S)[0]:
                raise InvalidInputError(
                    f"{path}: a named pipe (FIFO) that delivered nothing for {PIPE_WAIT_S:g} s "
                    f"({'no writer opened it, or its writer wrote nothing' if not chunks else 'its writer stopped writing'}); "
                    "start its writer first, or give a regular file")
            try:
                block = os.read(fd, 1 << 20)
            except BlockingIOError:
                continue
            if not block:
                return b"".join(chunks)
            chunks.append(block)
    finally:
        os.close(fd)


def _has_vertices(geometry):
    if _is(geometry, "Scene"):
        return any(len(getattr(g, "vertices", ())) for g in geometry.geometry.values())
    return len(getattr(geometry, "vertices", ())) > 0


def _flatten(scene, source):
    """Scene -> one Trimesh (meshes concatenated, transforms applied) or PointCloud.

    Raises:
      InvalidInputError: trimesh cannot flatten the scene (a corrupt file's geometry: face colors
        of another shape than its faces, ...), naming `source`.
    """
    trimesh = _trimesh()
    try:
        parts = scene.dump()
        meshes = [g for g in parts if isinstance(g, trimesh.Trimesh) and len(g.faces) > 0]
        if meshes:
            return meshes[0] if len(meshes) == 1 else trimesh.util.concatenate(meshes)
    except Exception as exc:  # trimesh's own errors for a scene it made of a broken file
        detail = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InvalidInputError(f"{source}: cannot flatten its scene into one mesh: {detail}") from None
    points = [np.asarray(g.vertices) for g in parts if hasattr(g, "vertices") and len(g.vertices)]
    if not points:
        raise InvalidInputError(f"{source}: empty geometry (no meshes or points)")
    return trimesh.PointCloud(np.concatenate(points, axis=0))


# --------------------------------------------------------------------------- export
MESH_FORMATS = ("ply", "obj", "off", "stl", "glb")  # hold triangles
POINT_FORMATS = ("ply", "obj", "glb", "xyz")  # hold a point cloud
OUTPUT_FORMATS = tuple(sorted(set(MESH_FORMATS) | set(POINT_FORMATS)))
_FLOAT32_FORMATS = ("glb", "ply", "stl")  # store coordinates as float32 (the text formats as decimals)


def _check_path(path):
    """``path`` if it is a str or os.PathLike; InvalidInputError otherwise."""
    if not isinstance(path, (str, os.PathLike)):
        raise InvalidInputError(f"path must be a str or Path, got {path!r:.80}")
    return path


def output_format(path, geometry=None) -> str:
    """The format a path's suffix names, checked against what it can hold; no I/O.

    Args:
      path: the output file (``out.ply``); the format is its lower-case suffix.
      geometry: optionally the Trimesh / PointCloud to be written: a point cloud needs one of
        :data:`POINT_FORMATS` (STL and OFF hold triangles only), a mesh one of :data:`MESH_FORMATS`.

    Returns:
      The format name (``"ply"``).

    Raises:
      InvalidInputError: no suffix, a format that cannot be written, or one that cannot hold
        `geometry`.
    """
    path = Path(_check_path(path))
    ext = path.suffix.lower().lstrip(".")
    if not ext:
        raise InvalidInputError(f"{path}: no extension to choose an output format; "
                                f"writable: {', '.join(OUTPUT_FORMATS)}")
    if ext not in OUTPUT_FORMATS:
        raise InvalidInputError(f"{path}: cannot write {path.suffix!r} files; writable: {', '.join(OUTPUT_FORMATS)}")
    if _is(geometry, "PointCloud") and ext not in POINT_FORMATS:
        raise InvalidInputError(f"{path}: a point cloud cannot be written as {ext.upper()} (it holds triangles "
                                f"only); use one of {', '.join('.' + e for e in POINT_FORMATS)}")
    if (isinstance(geometry, Surface) or _is(geometry, "Trimesh")) and ext not in MESH_FORMATS:
        raise InvalidInputError(f"{path}: a mesh cannot be written as {ext.upper()} (it holds points only); "
                                f"use one of {', '.join('.' + e for e in MESH_FORMATS)}")
    return ext


def encode(geometry, file_type) -> bytes:
    """The bytes of a Trimesh, PointCloud or Surface in a format of :data:`OUTPUT_FORMATS` (no I/O).

    Raises:
      InvalidInputError: not one of those, the geometry cannot be written in that format, or has
        NaN or inf coordinates, or coordinates beyond float32's range for a float32 format
        (PLY, STL, GLB) (written, it would be a file that jaxpose refuses to read).
    """
    if not (isinstance(geometry, Surface) or _is(geometry, "Trimesh") or _is(geometry, "PointCloud")):
        raise InvalidInputError(f"cannot write a {type(geometry).__name__}: give a Trimesh, PointCloud or "
                                "jaxpose.geometry.Surface (jaxpose.mesh.load makes one of an array or a file)")
    file_type = output_format(f"geometry.{file_type}", geometry)  # lower case: "PLY" is "ply" below
    vertices = np.asarray(geometry.vertices, np.float64)
    if not np.all(np.isfinite(vertices)):  # a file no reader takes back
        raise InvalidInputError(f"cannot write {type(geometry).__name__} with NaN or inf coordinates")
    if file_type in _FLOAT32_FORMATS and len(vertices):
        with np.errstate(over="ignore"):  # the cast each writer makes: past float32's range it is inf
            representable = np.all(np.isfinite(vertices.astype(np.float32)))
        if not representable:
            raise InvalidInputError(
                f"cannot write coordinates beyond float32's range (3.4e+38) as {file_type.upper()}, which stores "
                f"float32 (they would be inf): largest |coordinate| {np.abs(vertices).max():.3g}; write "
                f"a text format (.obj, .off for a mesh; .obj, .xyz for points), or rescale")
    surface = isinstance(geometry, Surface)
    if file_type == "off" and (surface or _is(geometry, "Trimesh")):
        try:
            return writers.off_bytes(geometry.vertices, geometry.faces)  # trimesh's bytes, sooner
        except writers.Unsupported:
            pass
    if file_type == "ply" and surface:
        try:
            return writers.ply_bytes(geometry.vertices, geometry.faces)  # trimesh's bytes of a plain mesh
        except writers.Unsupported:
            pass
    if surface:
        geometry = _trimesh_of(geometry)
    try:
        data = geometry.export(file_type=file_type)
    except Exception as exc:
        raise InvalidInputError(f"cannot write {type(geometry).__name__} as {file_type!r}: {exc}") from None
    return data.encode("utf-8") if isinstance(data, str) else bytes(data)


def export(mesh, path, force=False):
    """Write `mesh` to `path` atomically, in the format named by its extension.

    The format is checked against the geometry first (:func:`output_format`: a point cloud is
    refused for STL or OFF). Refuses an existing `path` unless `force`. Returns the path as a
    :class:`Path`.
    """
    path = Path(_check_path(path))
    data = encode(mesh, output_format(path, mesh))
    return write_atomic(path, data, force=force)


# --------------------------------------------------------------------------- example
def example_shape():
    """A capsule body with a thin outlying arm: the paper's hard case for centroids.

    Returns mesh : trimesh.Trimesh (watertight parts, concatenated)
    """
    trimesh = _trimesh()
    body = trimesh.creation.capsule(height=1.0, radius=0.5, count=[24, 24])
    arm = trimesh.creation.cylinder(radius=0.08, height=1.6, sections=16)
    arm.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0.0, 1.0, 0.0]))
    arm.apply_translation([1.2, 0.0, 0.3])
    hand = trimesh.creation.icosphere(subdivisions=2, radius=0.2)
    hand.apply_translation([2.0, 0.0, 0.3])
    return trimesh.util.concatenate([body, arm, hand])
