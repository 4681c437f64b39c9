"""Load a folder of classes: ``root/<class>/<mesh files>``, or a flat folder as one class."""
from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np
import trimesh

from jaxpose._validate import InvalidInputError
from jaxpose.io import formats, readers

__all__ = ["load_folder", "MESH_SUFFIXES"]

MESH_SUFFIXES = frozenset({".ply", ".obj", ".off", ".stl", ".glb", ".gltf"})


def _mesh_files(folder: Path) -> list[Path]:
    return sorted((p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in MESH_SUFFIXES),
                  key=lambda p: p.name)


def _load(path: Path) -> trimesh.Trimesh:
    mesh = _read_fast(path)
    if mesh is None:
        mesh = _read_trimesh(path)
    bad = int(np.count_nonzero(~np.all(np.isfinite(mesh.vertices), axis=1)))
    if bad:  # named here: the evaluation's own check names no file ("vertices has 1 rows with NaN ...")
        raise InvalidInputError(f"cannot read mesh {path}: {bad} of its {len(mesh.vertices)} vertices have NaN or inf "
                                "coordinates")
    mesh.metadata.setdefault("file_name", path.name)
    return mesh


def _read_trimesh(path: Path) -> trimesh.Trimesh:
    try:
        text = _text_fixed(path)
        if text is not None:  # what trimesh misreads: a byte-order mark, an OFF's comments (module docs)
            mesh = trimesh.load(io.BytesIO(text), file_type=path.suffix.lower()[1:], force="mesh", process=False,
                                resolver=trimesh.resolvers.FilePathResolver(str(path)))
        else:
            mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types on bad files
        raise InvalidInputError(f"cannot read mesh {path}: {exc}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InvalidInputError(f"{path} holds no triangle mesh")
    return mesh


def _text_fixed(path: Path):
    """A text mesh file's bytes as trimesh reads them right, where it would misread them, else None:
    without the UTF-8 byte-order mark that starts an OBJ, OFF or ASCII STL file (read as part of the
    first line: an OBJ's first vertex lost), an OFF file without its comments and an OBJ file with
    its tabs as spaces (:func:`jaxpose.io.formats.as_read`)."""
    suffix = path.suffix.lower()
    if suffix not in (".obj", ".off", ".stl"):
        return None
    data = path.read_bytes()
    if suffix == ".stl" and formats.binary_stl(data):
        return None
    fixed = formats.as_read(formats.without_bom(data), suffix[1:])
    return None if fixed == data else fixed


def _read_fast(path: Path):
    """``trimesh.load(path, force="mesh", process=False)`` through :mod:`jaxpose.io.readers`
    (vertices as stored, nothing merged; trimesh's names in the metadata), or None where they do
    not apply."""
    ext = path.suffix.lower().lstrip(".")
    if ext not in readers.READERS:
        return None
    try:
        data = path.read_bytes()
        if ext in ("obj", "off") or (ext == "stl" and not formats.binary_stl(data)):  # text: no byte-order mark
            data = formats.without_bom(data)
        loaded = readers.read(formats.as_read(data, ext), ext)
    except (readers.Unsupported, OSError):
        return None
    except InvalidInputError as exc:  # broken where trimesh would read part of it
        raise InvalidInputError(f"cannot read mesh {path}: {exc}") from None
    mesh = trimesh.Trimesh(**loaded.kwargs(), process=False)
    name = mesh.metadata.get("name", path.name)  # an ASCII STL's solid names it, as in trimesh
    mesh.metadata.update(name=name, node=name)
    return mesh


def load_folder(path) -> dict[str, list[trimesh.Trimesh]]:
    """Meshes of a folder, grouped by class.

    ``path`` holds one sub-folder per class (classes and files sorted by name; sub-folders
    without mesh files are skipped), or mesh files directly, then loaded as a single class
    named after the folder. Symbolic links are followed. Vertices are kept as stored
    (``process=False``), so meshes sharing a vertex order keep it (see
    :func:`jaxpose.evaluation.align_core`).

    Raises
    ------
    InvalidInputError : a path that is not a str or Path, missing folder, no mesh files, or an
    unreadable mesh.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise InvalidInputError(f"path must be a folder (str or Path), got {path!r:.80}")
    root = Path(path)
    if not root.is_dir():
        raise InvalidInputError(f"{root} is not a folder")
    files = _mesh_files(root)
    if files:
        return {root.resolve().name: [_load(f) for f in files]}
    classes = {}
    for sub in sorted((p for p in root.iterdir() if p.is_dir()), key=lambda p: p.name):
        sub_files = _mesh_files(sub)
        if sub_files:
            classes[sub.name] = [_load(f) for f in sub_files]
    if not classes:
        raise InvalidInputError(
            f"{root} holds no mesh files ({', '.join(sorted(MESH_SUFFIXES))}) nor class sub-folders with some")
    return classes
