"""Load a folder of classes: ``root/<class>/<mesh files>``, or a flat folder as one class."""
from __future__ import annotations

import os
import unicodedata
from pathlib import Path

import numpy as np
import trimesh

from jaxpose._validate import InvalidInputError, check_names
from jaxpose.io import readers
from jaxpose.io.mesh import read_stored

__all__ = ["load_folder", "MESH_SUFFIXES"]

MESH_SUFFIXES = frozenset({".ply", ".obj", ".off", ".stl", ".glb", ".gltf"})


def _mesh_files(folder: Path) -> list[Path]:
    """The mesh files of ``folder``, by name; hidden ones (``.name``: macOS's ``._pose.ply``
    resource forks, editors' copies) skipped, as ``jaxpose normalize`` skips them."""
    return sorted((p for p in folder.iterdir()
                   if not p.name.startswith(".") and p.is_file() and p.suffix.lower() in MESH_SUFFIXES),
                  key=lambda p: p.name)


def _load(path: Path) -> trimesh.Trimesh:
    """The mesh of a file as :func:`jaxpose.io.mesh.read_stored` reads it (the text preparation,
    decoding and checks of :func:`jaxpose.load`), vertices as stored (nothing merged), a Scene's
    meshes concatenated."""
    try:
        geometry = read_stored(path)
    except InvalidInputError as exc:
        raise InvalidInputError(f"cannot read mesh {exc}") from None  # (the message starts with the path)
    if isinstance(geometry, readers.Loaded):
        mesh = trimesh.Trimesh(**geometry.kwargs(), process=False)
    elif isinstance(geometry, trimesh.Scene):
        try:
            mesh = geometry.to_mesh() if hasattr(geometry, "to_mesh") else geometry.dump(concatenate=True)
        except Exception as exc:  # trimesh's own errors for a scene it made of a broken file
            raise InvalidInputError(f"cannot read mesh {path}: {exc}") from None
    else:
        mesh = geometry
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InvalidInputError(f"{path} holds no triangle mesh")
    name = mesh.metadata.get("name", path.name)  # an ASCII STL's solid names it, as trimesh.load(path) does
    mesh.metadata.update(name=name, node=name)
    bad = int(np.count_nonzero(~np.all(np.isfinite(mesh.vertices), axis=1)))
    if bad:  # named here: the evaluation's own check names no file ("vertices has 1 rows with NaN ...")
        raise InvalidInputError(f"cannot read mesh {path}: {bad} of its {len(mesh.vertices)} vertices have NaN or inf "
                                "coordinates")
    mesh.metadata.setdefault("file_name", path.name)
    return mesh


def load_folder(path, classes=None) -> dict[str, list[trimesh.Trimesh]]:
    """Meshes of a folder, grouped by class.

    ``path`` holds one sub-folder per class (classes and files sorted by name; sub-folders
    without mesh files are skipped), or mesh files directly, then loaded as a single class
    named after the folder. Hidden files and folders (``.name``: macOS's ``._pose.ply``, and
    ``jaxpose normalize``'s ``.jaxpose/`` records) are skipped, so an output folder of ``jaxpose
    normalize`` per class is read as its classes. Symbolic links are followed. Vertices are kept as stored (``process=False``), so meshes sharing a vertex order
    keep it (see :func:`jaxpose.evaluation.align_core`).

    ``classes``: None (every class), or a collection of class names to read, in the folder's
    order; the others' files are not read. ``load_folder("data", classes=["dog"])`` is
    ``{"dog": [...]}``.

    Raises
    ------
    InvalidInputError : a path that is not a str or Path, missing folder, no mesh files, mesh
    files beside class sub-folders with some (one class, or classes?), an unreadable mesh;
    ``classes`` that is one string, names none, names one twice, or names one the folder does not
    hold (the message names the classes it holds; a sub-folder of that name that holds no mesh
    files, "DIR/x holds no mesh files"; a class the name differs from only by case or Unicode
    normalization, "did you mean 'Dog'?"), before any mesh is read.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise InvalidInputError(f"path must be a folder (str or Path), got {path!r:.80}")
    root = Path(path)
    if not root.is_dir():
        raise InvalidInputError(f"{root} is not a folder")
    files = _mesh_files(root)
    subs = {sub: _mesh_files(sub) for sub in sorted((p for p in root.iterdir() if not p.name.startswith(".")
                                                      and p.is_dir()), key=lambda p: p.name)}
    subs = {sub: found for sub, found in subs.items() if found}
    if files and subs:  # (the files were taken as the one class, every class folder left out without a word)
        raise InvalidInputError(
            f"{root} holds mesh files ({', '.join(f.name for f in files[:3])}{', ...' if len(files) > 3 else ''}) "
            f"beside class folders with meshes ({', '.join(sub.name for sub in list(subs)[:3])}"
            f"{', ...' if len(subs) > 3 else ''}): is it one class or a folder of classes? Move the files into a "
            "class folder, or name one class's folder")
    found = {root.resolve().name: files} if files else {sub.name: paths for sub, paths in subs.items()}
    if not found:
        raise InvalidInputError(
            f"{root} holds no mesh files ({', '.join(sorted(MESH_SUFFIXES))}) nor class sub-folders with some")
    if classes is not None:  # (checked before any mesh is read; the others are not read)
        found = {name: found[name] for name in _chosen(classes, found, root)}
    return {name: [_load(f) for f in paths] for name, paths in found.items()}


def _chosen(classes, found, root):
    """The names of ``classes`` (each once, at least one) that ``found`` holds, in its order;
    InvalidInputError naming the unknown ones and the classes of ``root`` otherwise."""
    names = check_names(classes, "classes")
    if not names:
        raise InvalidInputError(f"classes names no class; give some of {', '.join(found)}, or None for all")
    missing = sorted((name for name in names if not isinstance(name, str) or name not in found), key=str)
    if missing:
        raise InvalidInputError(_missing(missing, found, root))
    return [name for name in found if name in names]


def _loose(name):
    """A class name as a person may mean it: one Unicode normalization (NFC: an ``é`` typed as one
    character or as ``e`` and its accent, as macOS stores names) and no case."""
    return unicodedata.normalize("NFC", name).casefold()


def _missing(missing, found, root):
    """Why the class names ``missing`` are not among the classes ``found`` in ``root``: a folder of
    that name that holds no mesh files is said to ("DIR/x holds no mesh files"), a name that differs
    from a class only by case or Unicode normalization names it ("no class 'dog' in DIR (did you mean
    'Dog'?)"; a normalization named, as the two look alike), the others
    are listed with the classes found."""
    try:  # (the folders as the listing names them: a case-insensitive file system finds 'dog' for 'Dog')
        folders = {p.name for p in root.iterdir() if not p.name.startswith(".") and p.is_dir()}
    except OSError:
        folders = set()
    close = {}
    for name in found:
        close.setdefault(_loose(name), name)
    parts, unknown = [], []
    for name in missing:
        if isinstance(name, str) and name in folders:
            parts.append(f"{root / name} holds no mesh files ({', '.join(sorted(MESH_SUFFIXES))})")
        elif isinstance(name, str) and _loose(name) in close:
            match = close[_loose(name)]
            form = (f": the same letters in another Unicode normalization, {ascii(name)} is not {ascii(match)}"
                    if unicodedata.normalize("NFC", name) == unicodedata.normalize("NFC", match) else "")
            parts.append(f"no class {name!r} in {root} (did you mean {match!r}?{form})")
        else:
            unknown.append(name)
    if unknown:
        parts.append(f"no classes {unknown} in {root}")
    return "; ".join(parts) + f"; found {sorted(found)}"  # (what there is to choose from, in every case)
