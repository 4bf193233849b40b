"""
Trust Region Reflective least squares with bounds: scipy's ``least_squares(method='trf')`` without scipy.optimize.

Why
    Importing scipy.optimize costs ~0.25 s of CPU on top of scipy.linalg (scipy 1.17 parses hundreds of docstrings at
    import), a third of a command's target (issue 13).  The bounded fits of ``bearing-id identify --method physical``
    (:func:`bearing_id.identify.physical.fit_physical`) and of ``bearing-id diagnose``
    (:func:`bearing_id.diagnose.select.fit`) were its only callers in those processes.

What
    :func:`least_squares` is scipy 1.17's ``least_squares(fun, x0, jac=..., bounds=(lb, ub), method='trf',
    x_scale=..., ftol=..., xtol=..., gtol=..., max_nfev=...)`` with a linear loss and ``tr_solver='exact'``,
    transcribed operation for operation: the starting point made strictly feasible, the Jacobian either the caller's
    (``jac``) or the forward-difference steps of ``approx_derivative`` (sqrt(eps) max(1, |x|), sign from x, flipped
    or shortened at a bound), ``trf_bounds`` (Coleman-Li scaling, ``x_scale='jac'`` or fixed scales, the SVD of the
    augmented Jacobian, More's trust-region solve, the reflective step selection, radius update and termination
    tests) and the ``VectorFunction`` cache (the Jacobian's base residual is the last one evaluated at that point).
    The same floating-point operations in the same order, so the same iterates bit for bit (``test/test_trf.py`` and
    ``test/test_diagnose_trf.py`` compare it with scipy's on the physical and diagnose problems and on random bounded
    problems).  Only what the callers use is kept: at least one finite bound (unbounded problems go to scipy), dense
    Jacobians.

    ``fun_many`` (optional) evaluates the residual at several points at once (the finite-difference Jacobian's
    columns); it must return what ``fun`` returns at each point, bit for bit.

Units: whatever the caller's residual and parameters are.
"""
from __future__ import annotations

from math import copysign

import numpy as np
from numpy.linalg import norm

EPS = float(np.finfo(float).eps)
FTOL = XTOL = GTOL = 1e-8


TERMINATION_MESSAGES = {     # scipy's, by status
    0: 'The maximum number of function evaluations is exceeded.',
    1: '`gtol` termination condition is satisfied.',
    2: '`ftol` termination condition is satisfied.',
    3: '`xtol` termination condition is satisfied.',
    4: 'Both `ftol` and `xtol` termination conditions are satisfied.'}


class Result:
    """What :func:`least_squares` returns (the fields of scipy's OptimizeResult that the callers read)."""

    def __init__(self, x, cost, fun, nfev, njev, status):
        self.x, self.cost, self.fun, self.nfev, self.njev, self.status = x, cost, fun, nfev, njev, status
        self.success = status > 0
        self.message = TERMINATION_MESSAGES[status]


# --------------------------------------------------------------------------- scipy/optimize/_lsq/common.py
def find_active_constraints(x, lb, ub, rtol=1e-10):
    """Return -1 / 1 / 0 per variable: lower bound, upper bound or no bound active (scipy's)."""
    active = np.zeros_like(x, dtype=int)
    if rtol == 0:
        active[x <= lb] = -1
        active[x >= ub] = 1
        return active
    lower_dist = x - lb
    upper_dist = ub - x
    lower_threshold = rtol * np.maximum(1, np.abs(lb))
    upper_threshold = rtol * np.maximum(1, np.abs(ub))
    lower_active = (np.isfinite(lb) & (lower_dist <= np.minimum(upper_dist, lower_threshold)))
    active[lower_active] = -1
    upper_active = (np.isfinite(ub) & (upper_dist <= np.minimum(lower_dist, upper_threshold)))
    active[upper_active] = 1
    return active


def make_strictly_feasible(x, lb, ub, rstep=1e-10):
    """Shift a point onto the interior of the box (scipy's)."""
    x_new = x.copy()
    active = find_active_constraints(x, lb, ub, rstep)
    lower_mask = np.equal(active, -1)
    upper_mask = np.equal(active, 1)
    if rstep == 0:
        x_new[lower_mask] = np.nextafter(lb[lower_mask], ub[lower_mask])
        x_new[upper_mask] = np.nextafter(ub[upper_mask], lb[upper_mask])
    else:
        x_new[lower_mask] = (lb[lower_mask] + rstep * np.maximum(1, np.abs(lb[lower_mask])))
        x_new[upper_mask] = (ub[upper_mask] - rstep * np.maximum(1, np.abs(ub[upper_mask])))
    tight_bounds = (x_new < lb) | (x_new > ub)
    x_new[tight_bounds] = 0.5 * (lb[tight_bounds] + ub[tight_bounds])
    return x_new


def intersect_trust_region(x, s, Delta):
    """Return the two t at which ||x + s t|| = Delta (scipy's)."""
    a = np.dot(s, s)
    if a == 0:
        raise ValueError('`s` is zero.')
    b = np.dot(x, s)
    c = np.dot(x, x) - Delta**2
    if c > 0:
        raise ValueError('`x` is not within the trust region.')
    d = np.sqrt(b * b - a * c)
    q = -(b + copysign(d, b))
    t1 = q / a
    t2 = c / q
    if t1 < t2:
        return t1, t2
    return t2, t1


def solve_lsq_trust_region(n, m, uf, s, V, Delta, initial_alpha=None, rtol=0.01, max_iter=10):
    """Solve the trust-region least-squares subproblem from the SVD (More's method, scipy's)."""
    def phi_and_derivative(alpha, suf, s, Delta):
        denom = s**2 + alpha
        p_norm = norm(suf / denom)
        phi = p_norm - Delta
        phi_prime = -np.sum(suf ** 2 / denom**3) / p_norm
        return phi, phi_prime

    suf = s * uf
    if m >= n:
        threshold = EPS * m * s[0]
        full_rank = s[-1] > threshold
    else:
        full_rank = False
    if full_rank:
        p = -V.dot(uf / s)
        if norm(p) <= Delta:
            return p, 0.0, 0
    alpha_upper = norm(suf) / Delta
    if full_rank:
        phi, phi_prime = phi_and_derivative(0.0, suf, s, Delta)
        alpha_lower = -phi / phi_prime
    else:
        alpha_lower = 0.0
    if initial_alpha is None or not full_rank and initial_alpha == 0:
        alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper)**0.5)
    else:
        alpha = initial_alpha
    for it in range(max_iter):
        if alpha < alpha_lower or alpha > alpha_upper:
            alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper)**0.5)
        phi, phi_prime = phi_and_derivative(alpha, suf, s, Delta)
        if phi < 0:
            alpha_upper = alpha
        ratio = phi / phi_prime
        alpha_lower = max(alpha_lower, alpha - ratio)
        alpha -= (phi + Delta) * ratio / Delta
        if np.abs(phi) < rtol * Delta:
            break
    p = -V.dot(suf / (s**2 + alpha))
    p *= Delta / norm(p)
    return p, alpha, it + 1


def update_tr_radius(Delta, actual_reduction, predicted_reduction, step_norm, bound_hit):
    """Return the new trust radius and the reduction ratio (scipy's)."""
    if predicted_reduction > 0:
        ratio = actual_reduction / predicted_reduction
    elif predicted_reduction == actual_reduction == 0:
        ratio = 1
    else:
        ratio = 0
    if ratio < 0.25:
        Delta = 0.25 * step_norm
    elif ratio > 0.75 and bound_hit:
        Delta *= 2.0
    return Delta, ratio


def build_quadratic_1d(J, g, s, diag=None, s0=None):
    """Return the coefficients of the quadratic model along s (scipy's)."""
    v = J.dot(s)
    a = np.dot(v, v)
    if diag is not None:
        a += np.dot(s * diag, s)
    a *= 0.5
    b = np.dot(g, s)
    if s0 is not None:
        u = J.dot(s0)
        b += np.dot(u, v)
        c = 0.5 * np.dot(u, u) + np.dot(g, s0)
        if diag is not None:
            b += np.dot(s0 * diag, s)
            c += 0.5 * np.dot(s0 * diag, s0)
        return a, b, c
    return a, b


def minimize_quadratic_1d(a, b, lb, ub, c=0):
    """Minimise a t^2 + b t + c on [lb, ub] (scipy's)."""
    t = [lb, ub]
    if a != 0:
        extremum = -0.5 * b / a
        if lb < extremum < ub:
            t.append(extremum)
    t = np.asarray(t)
    y = t * (a * t + b) + c
    min_index = np.argmin(y)
    return t[min_index], y[min_index]


def evaluate_quadratic(J, g, s, diag=None):
    """Return the quadratic model's value at the step s (1-D, scipy's)."""
    Js = J.dot(s)
    q = np.dot(Js, Js)
    if diag is not None:
        q += np.dot(s * diag, s)
    l_ = np.dot(s, g)
    return 0.5 * q + l_


def in_bounds(x, lb, ub):
    """Return True when lb <= x <= ub everywhere."""
    return np.all((x >= lb) & (x <= ub))


def step_size_to_bound(x, s, lb, ub):
    """Return the step along s to the nearest bound and which bounds it hits (scipy's)."""
    non_zero = np.nonzero(s)
    s_non_zero = s[non_zero]
    steps = np.empty_like(x)
    steps.fill(np.inf)
    with np.errstate(over='ignore'):
        steps[non_zero] = np.maximum((lb - x)[non_zero] / s_non_zero, (ub - x)[non_zero] / s_non_zero)
    min_step = np.min(steps)
    return min_step, np.equal(steps, min_step) * np.sign(s).astype(int)


def CL_scaling_vector(x, g, lb, ub):  # noqa: N802  (scipy's name)
    """Return the Coleman-Li scaling vector and its derivative (scipy's)."""
    v = np.ones_like(x)
    dv = np.zeros_like(x)
    mask = (g < 0) & np.isfinite(ub)
    v[mask] = ub[mask] - x[mask]
    dv[mask] = -1
    mask = (g > 0) & np.isfinite(lb)
    v[mask] = x[mask] - lb[mask]
    dv[mask] = 1
    return v, dv


def compute_jac_scale(J, scale_inv_old=None):
    """Return the Jacobian's column scaling (x_scale='jac', scipy's)."""
    scale_inv = np.sum(J**2, axis=0)**0.5
    if scale_inv_old is None:
        scale_inv[scale_inv == 0] = 1
    else:
        scale_inv = np.maximum(scale_inv, scale_inv_old)
    return 1 / scale_inv, scale_inv


def check_termination(dF, F, dx_norm, x_norm, ratio, ftol, xtol):  # noqa: N803
    """Return scipy's termination status (2 ftol, 3 xtol, 4 both) or None."""
    ftol_satisfied = dF < ftol * F and ratio > 0.25
    xtol_satisfied = dx_norm < xtol * (xtol + x_norm)
    if ftol_satisfied and xtol_satisfied:
        return 4
    elif ftol_satisfied:
        return 2
    elif xtol_satisfied:
        return 3
    return None


# --------------------------------------------------------------------------- scipy/optimize/_numdiff.py (2-point)
def fd_steps(x0, lb, ub):
    """Return approx_derivative's 2-point absolute steps at x0 inside [lb, ub] (relative sqrt(eps))."""
    sign_x0 = (x0 >= 0).astype(float) * 2 - 1
    h = EPS**0.5 * sign_x0 * np.maximum(1.0, np.abs(x0))
    if np.all((lb == -np.inf) & (ub == np.inf)):
        return h
    h_adjusted = h.copy()
    lower_dist = x0 - lb
    upper_dist = ub - x0
    x = x0 + h
    violated = (x < lb) | (x > ub)
    fitting = np.abs(h) <= np.maximum(lower_dist, upper_dist)
    h_adjusted[violated & fitting] *= -1
    forward = (upper_dist >= lower_dist) & ~fitting
    h_adjusted[forward] = upper_dist[forward]
    backward = (upper_dist < lower_dist) & ~fitting
    h_adjusted[backward] = -lower_dist[backward]
    return h_adjusted


def fd_jacobian(fun_many, x0, f0, lb, ub):
    """Return the forward-difference Jacobian (m, n) at x0 with base residual f0 (approx_derivative's 2-point)."""
    n = x0.size
    h = fd_steps(x0, lb, ub)
    pts = []
    for i in range(n):
        x1 = np.copy(x0)
        x1[i] = x0[i] + h[i]
        pts.append(x1)
    f_evals = fun_many(pts)
    J_transposed = np.empty((n, f0.size))
    for i in range(n):
        J_transposed[i] = (np.atleast_1d(f_evals[i]) - f0) / ((x0[i] + h[i]) - x0[i])
    return J_transposed.T


# --------------------------------------------------------------------------- scipy/optimize/_lsq/trf.py
def select_step(x, J_h, diag_h, g_h, p, p_h, d, Delta, lb, ub, theta):
    """Select the best step according to Trust Region Reflective algorithm (scipy's)."""
    if in_bounds(x + p, lb, ub):
        p_value = evaluate_quadratic(J_h, g_h, p_h, diag=diag_h)
        return p, p_h, -p_value
    p_stride, hits = step_size_to_bound(x, p, lb, ub)
    r_h = np.copy(p_h)
    r_h[hits.astype(bool)] *= -1
    r = d * r_h
    p *= p_stride
    p_h *= p_stride
    x_on_bound = x + p
    _, to_tr = intersect_trust_region(p_h, r_h, Delta)
    to_bound, _ = step_size_to_bound(x_on_bound, r, lb, ub)
    r_stride = min(to_bound, to_tr)
    if r_stride > 0:
        r_stride_l = (1 - theta) * p_stride / r_stride
        if r_stride == to_bound:
            r_stride_u = theta * to_bound
        else:
            r_stride_u = to_tr
    else:
        r_stride_l = 0
        r_stride_u = -1
    if r_stride_l <= r_stride_u:
        a, b, c = build_quadratic_1d(J_h, g_h, r_h, s0=p_h, diag=diag_h)
        r_stride, r_value = minimize_quadratic_1d(a, b, r_stride_l, r_stride_u, c=c)
        r_h *= r_stride
        r_h += p_h
        r = r_h * d
    else:
        r_value = np.inf
    p *= theta
    p_h *= theta
    p_value = evaluate_quadratic(J_h, g_h, p_h, diag=diag_h)
    ag_h = -g_h
    ag = d * ag_h
    to_tr = Delta / norm(ag_h)
    to_bound, _ = step_size_to_bound(x, ag, lb, ub)
    if to_bound < to_tr:
        ag_stride = theta * to_bound
    else:
        ag_stride = to_tr
    a, b = build_quadratic_1d(J_h, g_h, ag_h, diag=diag_h)
    ag_stride, ag_value = minimize_quadratic_1d(a, b, 0, ag_stride)
    ag_h *= ag_stride
    ag *= ag_stride
    if p_value < r_value and p_value < ag_value:
        return p, p_h, -p_value
    elif r_value < p_value and r_value < ag_value:
        return r, r_h, -r_value
    return ag, ag_h, -ag_value


def least_squares(fun, x0, lb, ub, *, jac=None, x_scale='jac', ftol: float = FTOL, xtol: float = XTOL,
                  gtol: float = GTOL, max_nfev=None, fun_many=None, svd=None) -> Result:
    """
    Minimise 0.5 ||fun(x)||^2 subject to lb <= x <= ub: scipy's trf, step for step.

    ``fun`` (n,) -> (m,) real residual; ``x0`` (n,) inside the bounds; ``lb``, ``ub`` (n,) with at least one finite
    entry; ``jac`` (n,) -> (m, n) the Jacobian (None: scipy's 2-point finite differences); ``x_scale`` 'jac' or
    positive scales (a number or (n,)); ``ftol``, ``xtol``, ``gtol`` scipy's tolerances (>= machine epsilon);
    ``max_nfev`` as scipy's (None: 100 n; the Jacobian's evaluations are not counted, as in scipy); ``fun_many`` list
    of (n,) points -> list of residuals (default: ``fun`` at each).  ``svd``: the thin SVD of the augmented Jacobian
    (default scipy.linalg.svd, scipy's own gesdd: the same bits as scipy's trf; ``numpy.linalg.svd``, the same LAPACK
    routine in numpy's build, takes the same steps to rounding without importing scipy.linalg).  Returns
    :class:`Result` (x, cost = 0.5 ||f||^2, fun, nfev, njev, status, success, message as scipy's).
    """
    if svd is None:
        from scipy.linalg import svd

    x0 = np.atleast_1d(x0).astype(float)
    lb = np.asarray(lb, dtype=float)
    ub = np.asarray(ub, dtype=float)
    if lb.ndim == 0:
        lb = np.resize(lb, x0.size)
    if ub.ndim == 0:
        ub = np.resize(ub, x0.size)
    if np.all((lb == -np.inf) & (ub == np.inf)):
        raise ValueError('trf.least_squares handles bounded problems only (use scipy for unbounded ones)')
    if np.any(lb >= ub) or not in_bounds(x0, lb, ub):
        raise ValueError('inconsistent bounds or x0 outside them')
    if min(ftol, xtol, gtol) < EPS:
        raise ValueError('tolerances below machine epsilon are not supported')
    jac_scale = isinstance(x_scale, str) and x_scale == 'jac'
    if not jac_scale:
        x_scale = np.resize(np.asarray(x_scale, dtype=float), x0.shape)
        if not (np.all(np.isfinite(x_scale)) and np.all(x_scale > 0)):
            raise ValueError("x_scale must be 'jac' or positive numbers")
    x0 = make_strictly_feasible(x0, lb, ub)
    if fun_many is None:
        def fun_many(pts):
            return [fun(p) for p in pts]

    cache = {'x': x0.copy(), 'f': np.asarray(fun(x0.copy()), dtype=float)}

    def fun_c(x):
        # VectorFunction.fun: re-evaluates only at a new point
        if not np.array_equal(x, cache['x']):
            cache['x'] = np.array(x, dtype=float)
            cache['f'] = np.asarray(fun(x.copy()), dtype=float)
        return cache['f'].copy()

    def jac_c(x):
        fun_c(x)
        if jac is not None:             # VectorFunction: the caller's Jacobian at the point last evaluated
            return np.atleast_2d(np.asarray(jac(cache['x'].copy()), dtype=float))
        return fd_jacobian(fun_many, cache['x'].copy(), cache['f'], lb, ub)

    f0 = cache['f'].copy()
    if not np.all(np.isfinite(f0)):
        raise ValueError('Residuals are not finite in the initial point.')
    J0 = jac_c(x0)

    # trf_bounds, linear loss, tr_solver='exact'
    x = x0.copy()
    f = f0
    f_true = f.copy()
    nfev = 1
    J = J0
    njev = 1
    m, n = J.shape
    cost = 0.5 * np.dot(f, f)
    g = J.T.dot(f)
    if jac_scale:
        scale, scale_inv = compute_jac_scale(J)
    else:
        scale, scale_inv = x_scale, 1 / x_scale
    v, dv = CL_scaling_vector(x, g, lb, ub)
    v[dv != 0] *= scale_inv[dv != 0]
    Delta = norm(x0 * scale_inv / v**0.5)
    if Delta == 0:
        Delta = 1.0
    g_norm = norm(g * v, ord=np.inf)
    f_augmented = np.zeros(m + n)
    J_augmented = np.empty((m + n, n))
    if max_nfev is None:
        max_nfev = x0.size * 100
    alpha = 0.0
    termination_status = None
    while True:
        v, dv = CL_scaling_vector(x, g, lb, ub)
        g_norm = norm(g * v, ord=np.inf)
        if g_norm < gtol:
            termination_status = 1
        if termination_status is not None or nfev == max_nfev:
            break
        v[dv != 0] *= scale_inv[dv != 0]
        d = v**0.5 * scale
        diag_h = g * dv * scale
        g_h = d * g
        f_augmented[:m] = f
        J_augmented[:m] = J * d
        J_h = J_augmented[:m]
        J_augmented[m:] = np.diag(diag_h**0.5)
        U, s, V = svd(J_augmented, full_matrices=False)
        V = V.T
        uf = U.T.dot(f_augmented)
        theta = max(0.995, 1 - g_norm)
        actual_reduction = -1
        while actual_reduction <= 0 and nfev < max_nfev:
            p_h, alpha, n_iter = solve_lsq_trust_region(n, m, uf, s, V, Delta, initial_alpha=alpha)
            p = d * p_h
            step, step_h, predicted_reduction = select_step(x, J_h, diag_h, g_h, p, p_h, d, Delta, lb, ub, theta)
            x_new = make_strictly_feasible(x + step, lb, ub, rstep=0)
            f_new = fun_c(x_new)
            nfev += 1
            step_h_norm = norm(step_h)
            if not np.all(np.isfinite(f_new)):
                Delta = 0.25 * step_h_norm
                continue
            cost_new = 0.5 * np.dot(f_new, f_new)
            actual_reduction = cost - cost_new
            Delta_new, ratio = update_tr_radius(Delta, actual_reduction, predicted_reduction, step_h_norm,
                                                step_h_norm > 0.95 * Delta)
            step_norm = norm(step)
            termination_status = check_termination(actual_reduction, cost, step_norm, norm(x), ratio, ftol, xtol)
            if termination_status is not None:
                break
            alpha *= Delta / Delta_new
            Delta = Delta_new
        if actual_reduction > 0:
            x = x_new
            f = f_new
            f_true = f.copy()
            cost = cost_new
            J = jac_c(x)
            njev += 1
            g = J.T.dot(f)
            if jac_scale:
                scale, scale_inv = compute_jac_scale(J, scale_inv)
    if termination_status is None:
        termination_status = 0
    return Result(x=x, cost=cost, fun=f_true, nfev=nfev, njev=njev, status=termination_status)


__all__ = ['least_squares', 'fd_jacobian', 'fd_steps', 'Result']
