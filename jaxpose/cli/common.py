"""What the commands share: the OCSVM options' arguments, the one-line failure message; strict JSON text is :mod:`jaxpose.io.jsontext`'s."""
from __future__ import annotations

import sys

from ..config import OCSVM, check_instances
from ..errors import InvalidInputError
from ..io.atomic import check_creatable, check_output_file  # shared by the commands
from ..io.jsontext import json_text  # the commands' JSON records (benchmarks/ write theirs with it too)

__all__ = ["add_svm_options", "fail", "checked", "check_output_file", "check_creatable", "check_dataset_choice",
           "dataset_classes", "comma_names", "given_names", "variant_names", "json_text"]


def checked(convert, check):
    """An argparse ``type``: the text converted (``int``, ``float``, ...), then the library's own
    ``check`` of the value, so that a value out of range is a usage error (exit 2, naming it) before
    any work, as a malformed one is."""
    import argparse

    def parse(text):
        try:
            value = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"invalid {getattr(convert, '__name__', 'value')} value: {text!r}") from None
        try:
            return check(value)
        except InvalidInputError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    return parse


def check_folder_name(folder, flag):
    """Refuse a folder option given as an empty name (``--data ""``, an unset shell variable): the
    path "" is the working directory, whose sub-folders would be read as classes. None passes."""
    if folder is not None and not str(folder).strip():
        raise InvalidInputError(f"{flag} names no folder ({str(folder)!r}); give a folder of class folders, or leave "
                                f"{flag} out")


def check_dataset_choice(instances, classes, data=None):
    """``--instances`` (None: the command's default; the built-in dataset's only) and ``--classes``
    (None: all; of the built-in dataset, or of ``--data``'s folder ``data``), checked before any
    work (evaluate, tune): InvalidInputError, a usage error (exit 2). The names of ``--data``'s
    classes are :func:`dataset_classes`' to check (its folder is read there)."""
    check_folder_name(data, "--data")
    if instances is not None:  # at least 2 (a class's spread), at most DATASET_INSTANCES (built in memory)
        check_instances(instances, "--instances", 2)
        if data is not None:  # (it was ignored without a word)
            raise InvalidInputError("--instances chooses from the built-in dataset; --data takes every mesh of each "
                                    "class of DIR")
    if classes is not None:
        from .._validate import check_names  # (NumPy: at run time, not when the parser is built)

        check_names(given_names(classes, "--classes", "class", every=False), "--classes")  # some, each once
        if data is None:
            from ..datasets.procedural import _check_class

            for name in comma_names(classes):
                _check_class(name)


def dataset_classes(data, names, seed, instances):
    """``{class: [mesh, ...]}`` of ``--data`` and ``--classes`` (evaluate, tune: the one place both
    read them): the class folders of ``data`` (:func:`jaxpose.datasets.load_folder`), or with
    ``data`` None the built-in procedural dataset (``instances`` objects per class, drawn with
    ``seed``); ``names``, the classes of ``--classes`` (None: every class), take those alone.

    Raises:
      InvalidInputError: as ``load_folder`` and ``make_dataset``: a class that ``data`` does not
        hold (``no classes ['cat'] in DIR; found ['dog', 'horse']``; ``DIR/cat holds no mesh files``;
        ``no class 'dog' in DIR (did you mean 'Dog'?)``; before any mesh is read), an
        unknown class of the built-in dataset, a missing folder, an unreadable mesh.
    """
    from .. import datasets

    if data is None:
        return datasets.make_dataset(seed, instances=instances, classes=names)
    return datasets.load_folder(data, classes=names)


def comma_names(text):
    """A comma list's names (``--methods``, ``--rotation``, ``--classes``, ``--variants``), spaces
    around them dropped and empty ones left out: ``"robust, bbox,"`` is ``["robust", "bbox"]``."""
    return [name.strip() for name in text.split(",") if name.strip()]


def given_names(text, flag, what, every=True):
    """:func:`comma_names` of the comma-list option `flag` given as `text` (evaluate's and tune's
    ``--methods``, ``--variants``, ``--rotation``, ``--classes``: one rule), refusing a list that
    names none (``''``, ``','``: an unset shell variable; ``--methods ''`` ran every method) with
    InvalidInputError, a usage error: "--variants names no variant (''); give some,
    comma-separated, or all". `what`: what one name names; `every`: whether ``all`` is a choice
    of the option (it is said)."""
    names = comma_names(text)
    if not names:
        raise InvalidInputError(f"{flag} names no {what} ({text!r}); give some, comma-separated"
                                + (", or all" if every else ""))
    return names


def variant_names(text):
    """``--variants``' comma list (evaluate, tune): the names, spaces around them dropped; ``all``
    alone is every variant (:data:`jaxpose.evaluation.variants.VARIANTS`); a list that names none
    refused (:func:`given_names`). Unknown names are the caller's to refuse (with the valid ones)."""
    from ..evaluation.variants import VARIANTS  # (NumPy: at run time, not when the parser is built)

    names = given_names(text, "--variants", "variant")
    return list(VARIANTS) if names == ["all"] else names


def add_core_options(p):
    """``--align-core`` and ``--core-weight`` (evaluate, tune): the rigid-core alignment of each class
    (:func:`jaxpose.evaluation.alignment.align_classes`) and what the core is a share of."""
    p.add_argument("--align-core", action="store_true", help="rigidly align each class on its stable core first "
                   "(meshes of a class share their vertex order)")
    # the choices are alignment.CORE_WEIGHTS, written out: that module imports NumPy (test_cli_habits pins them equal)
    p.add_argument("--core-weight", choices=("vertices", "area"), default="vertices",
                   help="with --align-core: the stable core is a share of the vertices (default) or of the surface "
                        "area (the same whatever the meshing density)")


def check_core_options(align_core, core_weight):
    """``--core-weight`` without ``--align-core``: InvalidInputError, a usage error (exit 2)."""
    if core_weight != "vertices" and not align_core:
        raise InvalidInputError(f"--core-weight {core_weight} says how --align-core chooses the core; add --align-core")


def add_svm_options(p, count=OCSVM.count, seed="random seed"):
    """``--gamma``, ``--nu``, ``--count`` and ``--seed`` with :data:`jaxpose.config.OCSVM`'s defaults;
    ``seed``: what the command's seed seeds (its help text)."""
    p.add_argument("--gamma", type=float, default=OCSVM.gamma,
                   help=f"ocsvm: Gaussian kernel width (dimensionless, default {OCSVM.gamma:g})")
    p.add_argument("--nu", type=float, default=OCSVM.nu, help=f"ocsvm: slack in [0, 1] (default {OCSVM.nu:g})")
    p.add_argument("--count", type=int, default=count, help=f"ocsvm: surface samples per object (default {count})")
    p.add_argument("--seed", type=int, default=OCSVM.seed, help=f"{seed} (default {OCSVM.seed})")


def fail(message, code=1):
    text = " ".join(str(message).split()) or "failed"
    print(f"jaxpose: error: {text}", file=sys.stderr)
    return code


