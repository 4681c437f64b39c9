"""Files in and out: formats of tables, mesh and point-cloud files (:mod:`.mesh`), atomic writes (:mod:`.atomic`), strict JSON text (:mod:`.jsontext`).

The lowest layer above the validators: nothing here knows of occupancies, moments or poses.
"""
