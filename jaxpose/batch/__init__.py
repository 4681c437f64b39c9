"""Many files: inputs and plans (:mod:`.inputs`), one file's task (:mod:`.task`), the run
(:mod:`.batch`), its journal, workers (local pool, Dask), interrupts, and the transforms table.

Knows no math: each file goes through :func:`jaxpose.normalize_mesh`'s code.
"""
