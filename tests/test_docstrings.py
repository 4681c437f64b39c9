"""The docstring examples of the host-only modules run and print what they show (doctest).

Only modules whose examples run on the host without compiling a program (NumPy, SciPy, plain
Python; under 0.5 s together, most of it importing SciPy): the examples that compile (``jaxpose.depth``, ``jaxpose.weighted``,
``jaxpose.occupancy.grid``, ``jaxpose.pose.pose``, ``jaxpose.backend``) and the process pool's are
run by ``python -m pytest --doctest-modules jaxpose -n 0`` (docs/testing.md), not by the suite.
"""
import doctest
import importlib

import pytest

HOST_ONLY = ["jaxpose.config", "jaxpose.batch.inputs", "jaxpose.pose.result", "jaxpose.occupancy.solid", "jaxpose.cli.common"]


@pytest.mark.parametrize("name", HOST_ONLY)
def test_examples_print_what_they_show(name):
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS, report=True)
    assert result.attempted > 0, f"{name} has no example"
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples of {name} failed (printed above)"
