"""Support vector data description, the one-class SVM of the paper (eqs. 1-3).

:func:`fit_svdd` solves the dual (:mod:`.problem`) by projected gradient (:mod:`.pg`) or SMO
(:mod:`.smo`) and differentiates the solution implicitly (:mod:`.implicit`); :mod:`.secant`
gives the trend derivative in nu; :func:`decision_function` is eq. 3.
"""
from .fit import PG_MAX_M, SMO_BUDGET, fit_svdd, pick_solver, solve_svdd
from .problem import SVDD, decision_function, decision_value_and_grad, kkt_violation, upper_bound
from .smo import SMO_GROUP

__all__ = ["SVDD", "fit_svdd", "solve_svdd", "decision_function", "decision_value_and_grad", "kkt_violation",
           "upper_bound", "pick_solver", "PG_MAX_M", "SMO_BUDGET", "SMO_GROUP"]
