"""The docstring examples of the host-only modules run and print what they show (doctest).

Only modules whose examples run on the host without compiling a program (NumPy, SciPy, plain
Python; under 0.5 s together, most of it importing SciPy): the examples that compile (``jaxpose.depth``, ``jaxpose.weighted``,
``jaxpose.occupancy.grid``, ``jaxpose.pose.pose``, ``jaxpose.backend``) and the process pool's are
run by ``python -m pytest --doctest-modules jaxpose -n 0`` (docs/testing.md), not by the suite.
"""
import doctest
import importlib

import pytest

HOST_ONLY = ["jaxpose.config", "jaxpose.batch.inputs", "jaxpose.pose.result", "jaxpose.occupancy.solid", "jaxpose.io.jsontext"]


@pytest.mark.parametrize("name", HOST_ONLY)
def test_examples_print_what_they_show(name):
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS, report=True)
    assert result.attempted > 0, f"{name} has no example"
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples of {name} failed (printed above)"


def test_the_local_cluster_example_is_a_script_that_runs():
    """jaxpose.batch.workers.local_cluster's example, run as a script, starts worker processes that
    import the script's __main__ again (Dask's spawn): it needs the `if __name__ == "__main__":`
    guard, and its own imports (it was a skipped doctest using normalize_files unimported,
    unguarded). Checked statically: the block compiles, every name it reads is imported or bound
    in it, and the cluster starts under the guard."""
    import ast
    import builtins
    import textwrap

    from jaxpose.batch import workers

    doc = workers.local_cluster.__doc__
    assert "::\n" in doc[doc.index("Example"):], "the example is not a script (a literal block)"
    block = doc[doc.index("::\n", doc.index("Example")) + 3:]  # the literal block after "Example ...::"
    code = textwrap.dedent("\n".join(line for line in block.splitlines() if not line.strip().startswith(">>>")))
    tree = ast.parse(code)
    bound = {alias.asname or alias.name.split(".")[0] for node in ast.walk(tree)
             if isinstance(node, (ast.Import, ast.ImportFrom)) for alias in node.names}
    bound |= {n.id for n in ast.walk(tree) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)}
    bound |= {n.optional_vars.id for n in ast.walk(tree) if isinstance(n, ast.withitem)
              and isinstance(n.optional_vars, ast.Name)}
    read = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Load)}
    assert read - bound - set(dir(builtins)) == set(), code
    guards = [node for node in tree.body if isinstance(node, ast.If) and ast.unparse(node.test) in
              ("__name__ == '__main__'", '__name__ == "__main__"')]
    assert guards, code
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", None) == "local_cluster"]
    assert calls and all(any(c in ast.walk(g) for g in guards) for c in calls), code
