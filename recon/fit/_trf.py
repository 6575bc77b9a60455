"""scipy's unbounded trust-region reflective loop (``trf_no_bounds``), specialised to what the fitters call.

``least_squares(fun, x0, jac=jac, loss="soft_l1", f_scale=s, x_scale="jac", max_nfev=k)`` without bounds runs
``scipy.optimize._lsq.trf.trf_no_bounds`` with ``tr_solver="exact"`` and ``ftol = xtol = gtol = 1e-8``. This is
that loop (scipy 1.17) with the same floating-point operations in the same order on the same arrays, so the
result is bit-identical; what it leaves out is the Python around them, which on the decomposition's fits (a few
hundred points, 4–7 parameters, ~10 iterations) is most of a fit: the ``scipy.linalg.svd`` wrapper (its input
checks, and a LAPACK workspace query per call: the workspace is the same for the same shape and is kept), the
loss function's closure, ``np.linalg.norm``'s dispatch, the helper calls and ``OptimizeResult``.

The differential test ``test_direct_trust_region_loop_is_least_squares_bit_for_bit`` compares it with
``least_squares`` itself. :func:`lm_plain` is the same for ``method="lm"``: MINPACK's ``lmder`` called as
``least_squares`` calls it, without its ``VectorFunction`` (a copy and an ``array_equal`` per evaluation).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import get_lapack_funcs

_EPS = np.finfo(float).eps
_sqrt = np.sqrt
_isfinite = np.isfinite
_gesdd = get_lapack_funcs("gesdd", (np.zeros((2, 2)),), ilp64="preferred")
_gesdd_lwork = get_lapack_funcs("gesdd_lwork", (np.zeros((2, 2)),), ilp64="preferred")
_LWORK: dict = {}


class TrfResult:
    """The fields of scipy's ``OptimizeResult`` the fitters read."""

    __slots__ = ("x", "fun", "cost", "nfev", "njev", "status")

    def __init__(self, x, fun, cost, nfev, njev, status):
        self.x, self.fun, self.cost, self.nfev, self.njev, self.status = x, fun, cost, nfev, njev, status


def _workspace(m: int, n: int) -> int:
    """LAPACK's optimal workspace for gesdd of an m × n matrix, as ``scipy.linalg.svd`` asks for it (its
    ``_compute_lwork``: the query's float64 answer truncated to an integer), from the public ``gesdd_lwork``."""
    work, info = _gesdd_lwork(m, n, compute_uv=True, full_matrices=False)
    if info != 0:
        raise ValueError(f"Internal work array size computation failed: {info}")
    return int(work.real)


def _svd(a):
    """``scipy.linalg.svd(a, full_matrices=False)`` (gesdd) for a C-contiguous float64 matrix."""
    m, n = a.shape
    lwork = _LWORK.get((m, n))
    if lwork is None:
        lwork = _LWORK[(m, n)] = _workspace(m, n)
    if not _isfinite(a).all():  # scipy.linalg.svd's check_finite
        raise ValueError("array must not contain infs or NaNs")
    u, s, v, info = _gesdd(a, compute_uv=True, lwork=lwork, full_matrices=False, overwrite_a=False)
    if info > 0:
        raise np.linalg.LinAlgError("SVD did not converge")
    if info < 0:
        raise ValueError(f"illegal value in {-info}th argument of internal gesdd")
    return u, s, v


def _norm(x):
    return _sqrt(x.dot(x))  # np.linalg.norm(x) of a 1-D float array


def _solve_lsq_trust_region(n, m, uf, s, V, Delta, initial_alpha, rtol=0.01, max_iter=10):
    """``scipy.optimize._lsq.common.solve_lsq_trust_region``, inlined."""
    suf = s * uf

    if m >= n:
        threshold = _EPS * m * s[0]
        full_rank = s[-1] > threshold
    else:
        full_rank = False

    if full_rank:
        p = -V.dot(uf / s)
        if _norm(p) <= Delta:
            return p, 0.0

    alpha_upper = _norm(suf) / Delta

    if full_rank:
        denom = s**2 + 0.0
        p_norm = _norm(suf / denom)
        phi = p_norm - Delta
        phi_prime = -(suf**2 / denom**3).sum() / p_norm
        alpha_lower = -phi / phi_prime
    else:
        alpha_lower = 0.0

    if initial_alpha is None or not full_rank and initial_alpha == 0:
        # scipy's trust-region constants (lsq_linear / trf, Moré 1983): kept as scipy has them
        alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper) ** 0.5)
    else:
        alpha = initial_alpha

    s2 = s**2
    for _ in range(max_iter):
        if alpha < alpha_lower or alpha > alpha_upper:
            # scipy's trust-region constants, as above
            alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper) ** 0.5)

        denom = s2 + alpha
        p_norm = _norm(suf / denom)
        phi = p_norm - Delta
        phi_prime = -(suf**2 / denom**3).sum() / p_norm

        if phi < 0:
            alpha_upper = alpha

        ratio = phi / phi_prime
        alpha_lower = max(alpha_lower, alpha - ratio)
        alpha -= (phi + Delta) * ratio / Delta

        if np.abs(phi) < rtol * Delta:
            break

    p = -V.dot(suf / (s**2 + alpha))
    p *= Delta / _norm(p)
    return p, alpha


def _soft_l1(f, f_scale: float):
    """scipy's soft_l1 ``loss_function`` with ``cost_only=False``: ``rho0 * fs², rho1, rho2 / fs²``."""
    fs2 = f_scale**2
    t = 1 + (f / f_scale) ** 2
    rho0 = 2 * (t**0.5 - 1)
    rho1 = t**-0.5
    rho2 = -0.5 * t**-1.5
    rho0 *= fs2
    rho2 /= fs2
    return rho0, rho1, rho2


def _soft_l1_rho12(t, fs2: float):
    """:func:`_soft_l1`'s rho1 and rho2 of the same t (its rho0 only feeds the cost: :func:`_soft_l1_cost`)."""
    rho1 = t**-0.5
    rho2 = -0.5 * t**-1.5
    rho2 /= fs2
    return rho1, rho2


def _soft_l1_cost(f, f_scale: float):
    """``cost_only(f)`` and the t it is made of (:func:`_soft_l1` forms the same t from the same f on a taken step)."""
    t = 1 + (f / f_scale) ** 2
    return 0.5 * f_scale**2 * np.add.reduce(2 * (t**0.5 - 1)), t


def _col_norms(J):
    """``(J**2).sum(axis=0) ** 0.5``: numpy sums the rows in order, as einsum does for two or more C-ordered columns
    (a third of the cost of reducing over rows of 4-7)."""
    if J.shape[1] >= 2 and J.flags.c_contiguous:
        return np.einsum("ij,ij->j", J, J) ** 0.5
    return (J**2).sum(axis=0) ** 0.5


def _scale_for_loss(J, f, rho1, rho2):
    """scipy's ``scale_for_robust_loss_function``: J and f scaled in place."""
    J_scale = rho1 + 2 * rho2 * f**2
    J_scale[J_scale < _EPS] = _EPS
    J_scale **= 0.5
    f *= rho1 / J_scale
    J *= J_scale[:, np.newaxis]
    return J, f


def _tr_radius(Delta: float, actual_reduction, predicted_reduction, step_h_norm: float):
    """scipy's ``update_tr_radius``: the next trust radius and the reduction ratio."""
    if predicted_reduction > 0:
        ratio = actual_reduction / predicted_reduction
    elif predicted_reduction == actual_reduction == 0:
        ratio = 1
    else:
        ratio = 0
    if ratio < 0.25:
        return 0.25 * step_h_norm, ratio
    # scipy's trust-region radius update (step within 5% of the radius): kept as scipy has it
    if ratio > 0.75 and step_h_norm > 0.95 * Delta:
        return Delta * 2.0, ratio
    return Delta, ratio


def _termination(actual_reduction, cost, ratio, step_norm: float, x_norm: float, ftol: float, xtol: float):
    """scipy's ``check_termination``: 4 (ftol and xtol), 2 (ftol), 3 (xtol) or None."""
    ftol_satisfied = actual_reduction < ftol * cost and ratio > 0.25
    xtol_satisfied = step_norm < xtol * (xtol + x_norm)
    if ftol_satisfied and xtol_satisfied:
        return 4
    if ftol_satisfied:
        return 2
    if xtol_satisfied:
        return 3
    return None


def trf_soft_l1(fun, jac, x0, f0, J0, f_scale: float, max_nfev: int, ftol=1e-8, xtol=1e-8, gtol=1e-8):
    """``trf_no_bounds(fun, jac, x0, f0, J0, ftol, xtol, gtol, max_nfev, "jac", soft_l1 loss, "exact", {}, 0)``.

    ``fun(x)`` (m,) and ``jac(x)`` (m, n) float arrays (fresh ones: they are scaled in place, as scipy does);
    ``x0`` (n,) float, ``f0 = fun(x0)``, ``J0 = jac(x0)``. Returns a :class:`TrfResult`; raises what scipy's
    SVD raises (``ValueError`` on non-finite Jacobians, ``LinAlgError`` when it does not converge).
    """
    fs2 = f_scale**2
    x = x0.copy()
    f = f0
    f_true = f.copy()
    nfev = 1
    J = J0
    njev = 1
    m, n = J.shape

    rho0, rho1, rho2 = _soft_l1(f, f_scale)
    cost = 0.5 * rho0.sum()
    J, f = _scale_for_loss(J, f, rho1, rho2)
    g = J.T.dot(f)

    scale_inv = _col_norms(J)
    scale_inv[scale_inv == 0] = 1
    scale = 1 / scale_inv

    Delta = _norm(x0 * scale_inv)
    if Delta == 0:
        Delta = 1.0

    alpha = 0.0
    termination_status = None

    while True:
        g_norm = np.abs(g).max(initial=0)
        if g_norm < gtol:
            termination_status = 1
        if termination_status is not None or nfev == max_nfev:
            break

        d = scale
        g_h = d * g
        J_h = J * d
        U, s, V = _svd(J_h)
        V = V.T
        uf = U.T.dot(f)

        actual_reduction = -1
        while actual_reduction <= 0 and nfev < max_nfev:
            step_h, alpha = _solve_lsq_trust_region(n, m, uf, s, V, Delta, alpha)

            Js = J_h.dot(step_h)
            predicted_reduction = -(0.5 * np.dot(Js, Js) + np.dot(step_h, g_h))
            step = d * step_h
            x_new = x + step
            f_new = fun(x_new)
            nfev += 1

            step_h_norm = _norm(step_h)

            if not _isfinite(f_new).all():
                Delta = 0.25 * step_h_norm
                continue

            cost_new, t_new = _soft_l1_cost(f_new, f_scale)
            actual_reduction = cost - cost_new
            Delta_new, ratio = _tr_radius(Delta, actual_reduction, predicted_reduction, step_h_norm)
            termination_status = _termination(actual_reduction, cost, ratio, _norm(step), _norm(x), ftol, xtol)
            if termination_status is not None:
                break

            alpha *= Delta / Delta_new
            Delta = Delta_new

        if actual_reduction > 0:
            x = x_new
            f = f_new
            f_true = f.copy()
            cost = cost_new
            J = jac(x)
            njev += 1
            rho1, rho2 = _soft_l1_rho12(t_new, fs2)  # t_new: f_new's, and f is f_new
            J, f = _scale_for_loss(J, f, rho1, rho2)
            g = J.T.dot(f)
            scale_inv = np.maximum(_col_norms(J), scale_inv)
            scale = 1 / scale_inv

    if termination_status is None:
        termination_status = 0
    return TrfResult(x, f_true, cost, nfev, njev, termination_status)


#: scipy's ``FROM_MINPACK_TO_COMMON``: MINPACK's ``info`` as ``least_squares``'s ``status``.
_MINPACK_STATUS = {0: -1, 1: 2, 2: 3, 3: 4, 4: 1, 5: 0}


def lm_plain(fun, jac, x0, max_nfev: int, ftol=1e-8, xtol=1e-8, gtol=1e-8):
    """``least_squares(fun, x0, jac=jac, method="lm", x_scale="jac", max_nfev=max_nfev)`` (scipy 1.17's
    ``call_minpack``: ``diag=None``, ``factor=100``, rows of J as returned), bit for bit.

    ``fun(x)`` (m,) and ``jac(x)`` (m, n) float arrays, m ≥ n. Returns a :class:`TrfResult` (``cost`` and ``njev``
    as scipy's); raises ``ValueError`` when the residuals at ``x0`` are not finite, as ``least_squares`` does.
    """
    from scipy.optimize import _minpack  # here: scipy.optimize is 0.1 s of start-up the trust-region loop never uses

    if not callable(getattr(_minpack, "_lmder", None)):  # a private call: a scipy without it gets the public one
        from scipy.optimize import least_squares

        res = least_squares(fun, x0, jac=jac, method="lm", x_scale="jac", max_nfev=max_nfev)
        return TrfResult(res.x, res.fun, res.cost, res.nfev, res.njev, res.status)
    x0 = np.atleast_1d(x0).astype(float)
    f0 = np.atleast_1d(fun(x0))
    if not np.all(np.isfinite(f0)):
        raise ValueError("Residuals are not finite in the initial point.")  # as least_squares
    if f0.size < x0.size:
        raise ValueError("Method 'lm' doesn't work when the number of residuals is less than the number of variables.")
    x, info, status = _minpack._lmder(lambda x: np.atleast_1d(fun(x)), lambda x: np.atleast_2d(jac(x)), x0.copy(), (),
                                      True, False, ftol, xtol, gtol, max_nfev, 100.0, None)
    f = info["fvec"]
    return TrfResult(x, f, 0.5 * np.dot(f, f), info["nfev"], info.get("njev"), _MINPACK_STATUS[status])
