"""
Levenberg-Marquardt as MINPACK's lmder in numpy: scipy.optimize.least_squares(method='lm') without importing scipy.

Why
    The transient-aware 1X fit (:mod:`bearing_id.signals`) runs its small variable-projection problems (n <= 8
    parameters) through ``least_squares(..., method='lm', x_scale='jac')``, i.e. MINPACK's lmder, and the direct
    method (:mod:`bearing_id.identify.direct`) its 16-unknown output-error fits and their profile checks
    (:func:`least_squares`, scipy's result fields).  Importing scipy.optimize costs ~0.3-0.6 s of every process start
    (scipy 1.17 parses hundreds of docstrings at import); a command that needs no other scipy.optimize routine should
    not pay it (issue 13).

What
    :func:`lmder` is MINPACK-1's lmder (More, Garbow, Hillstrom 1980) step for step: the Jacobian's QR with
    qrfac's column pivoting (pivot order from the Gram matrix, the factorisation by LAPACK's Householder QR with
    qrfac's sign convention), lmpar (the Levenberg-Marquardt parameter by More's safeguarded Newton iteration,
    qrsolv's Givens rotations, in plain floats in MINPACK's order), the same step acceptance, trust-region update
    and convergence tests (ftol, xtol, gtol, maxfev, the machine-precision ones), with scipy's scaling
    (``x_scale='jac'``: MINPACK mode 1, diag from the first Jacobian's column norms, then their running maximum;
    numbers: mode 2, diag = 1 / x_scale) and scipy's ``factor`` 100.  The arithmetic differs from scipy's only in
    the order of floating-point sums, so it takes the same steps and its result equals scipy's to rounding
    (test/test_lm.py; the transient fits of test/test_transient_fast.py).  Where a run ends by ftol the last
    step's acceptance rests on rounding (actred is 1 - (|f1| / |f|)^2 of two norms equal to ~1e-10) in both.

Units: whatever the caller's residual and parameters are.
"""
from __future__ import annotations

import math

import numpy as np

_EPSMCH = float(np.finfo(float).eps)
_DWARF = float(np.finfo(float).tiny)


def _enorm(v) -> float:
    """Return the Euclidean norm of the vector ``v`` (MINPACK's enorm without its over/underflow scaling)."""
    return math.sqrt(float(np.dot(v, v)))


def _qrfac(a, f):
    """
    Pivoted QR of the Jacobian ``a`` (m, n), m >= n, with Q^T f: what MINPACK's qrfac (pivot = true) and lmder give.

    The pivot order is qrfac's rule (the column of largest norm orthogonal to the ones already taken), taken from
    the Gram matrix (n is small); the QR itself is LAPACK's Householder QR (dgeqrf: the same reflectors and the
    same sign of R's diagonal as qrfac) of [a P, f], whose last column gives Q^T f.  The Levenberg-Marquardt step
    does not depend on the pivoting in exact arithmetic (full rank), so a pivot picked differently between two
    columns of equal norm to rounding changes the result by rounding only.

    Returns (ipvt (n,) int, R (n, n) upper triangular, acnorm (n,) column norms of ``a``, qtf (n,) = (Q^T f)[:n]).
    """
    m, n = a.shape
    G = (a.T @ a).tolist()
    d = [G[i][i] for i in range(n)]
    acnorm = np.sqrt(np.einsum('ij,ij->j', a, a))
    ipvt = list(range(n))
    L = [[0.0] * n for _ in range(n)]                 # rows by pivot position
    for j in range(n):                                # pivoted Cholesky of the Gram matrix (plain floats): the order
        k = max(range(j, n), key=lambda i: (d[ipvt[i]], -i))
        if k != j:
            ipvt[j], ipvt[k] = ipvt[k], ipvt[j]
            L[j], L[k] = L[k], L[j]
        c = ipvt[j]
        piv = d[c]
        if not piv > 0.0:
            break
        ljj = math.sqrt(piv)
        Lj = L[j]
        Lj[j] = ljj
        Gc = G[c]
        for i in range(j + 1, n):
            Li = L[i]
            s = Gc[ipvt[i]]
            for t in range(j):
                s -= Li[t] * Lj[t]
            Li[j] = s / ljj
            d[ipvt[i]] -= Li[j] * Li[j]
    ipvt = np.array(ipvt)
    aug = np.empty((m, n + 1))
    aug[:, :n] = a[:, ipvt]
    aug[:, n] = f
    Ra = np.linalg.qr(aug, mode='r')
    return ipvt, Ra[:n, :n], acnorm, Ra[:n, n].copy()


def _qrsolv(r, ipvt, diag, qtb, sdiag):
    """
    Solve min |(A; D) x - (b; 0)| given the QR of A P (``r`` (n, n) upper triangle): MINPACK's qrsolv.

    ``r`` is a list of n row lists (scalar work in plain floats, in MINPACK's order); its strict lower triangle
    receives S's strict upper triangle (transposed), ``sdiag`` (list) S's diagonal.  Returns x (list, n).
    """
    n = len(r)
    x = [0.0] * n
    wa = list(qtb)
    for j in range(n):
        rj = r[j]
        for i in range(j, n):
            r[i][j] = rj[i]
        x[j] = rj[j]
    sqrt = math.sqrt
    for j in range(n):
        d = diag[ipvt[j]]
        if d != 0.0:
            for k in range(j, n):
                sdiag[k] = 0.0
            sdiag[j] = d
            qtbpj = 0.0
            for k in range(j, n):
                sk = sdiag[k]
                if sk == 0.0:
                    continue
                rk = r[k]
                rkk = rk[k]
                if abs(rkk) < abs(sk):
                    cotan = rkk / sk
                    sin = 0.5 / sqrt(0.25 + 0.25 * cotan ** 2)
                    cos = sin * cotan
                else:
                    tan = sk / rkk
                    cos = 0.5 / sqrt(0.25 + 0.25 * tan ** 2)
                    sin = cos * tan
                rk[k] = cos * rkk + sin * sk
                temp = cos * wa[k] + sin * qtbpj
                qtbpj = -sin * wa[k] + cos * qtbpj
                wa[k] = temp
                for i in range(k + 1, n):
                    ri = r[i]
                    temp = cos * ri[k] + sin * sdiag[i]
                    sdiag[i] = -sin * ri[k] + cos * sdiag[i]
                    ri[k] = temp
        sdiag[j] = r[j][j]
        r[j][j] = x[j]
    nsing = n
    for j in range(n):
        if sdiag[j] == 0.0 and nsing == n:
            nsing = j
        if nsing < n:
            wa[j] = 0.0
    for j in range(nsing - 1, -1, -1):
        s = 0.0
        for i in range(j + 1, nsing):
            s += r[i][j] * wa[i]
        wa[j] = (wa[j] - s) / sdiag[j]
    out = [0.0] * n
    for j in range(n):
        out[ipvt[j]] = wa[j]
    return out


def _div(a: float, b: float) -> float:
    """Return a / b with IEEE semantics (inf or nan for b == 0, as the Fortran and C code give) for Python floats."""
    if b != 0.0:
        return a / b
    if a == 0.0 or math.isnan(a):
        return math.nan
    return math.copysign(math.inf, a) * math.copysign(1.0, b)


def _enorm_list(v) -> float:
    """Return the Euclidean norm of a list of floats (sequential sum, as MINPACK's enorm in its normal range)."""
    s = 0.0
    for e in v:
        s += e * e
    return math.sqrt(s)


def _lmpar(r, ipvt, diag, qtb, delta, par):
    """
    Return (par, step x (list, n)) of the Levenberg-Marquardt subproblem: MINPACK's lmpar.

    ``r``: list of n row lists, R of the pivoted QR of the Jacobian in its upper triangle (its strict lower triangle
    is work space); ``ipvt``, ``diag``, ``qtb`` (the first n components of Q^T f): lists.
    """
    n = len(r)
    wa1 = list(qtb)
    nsing = n
    for j in range(n):
        if r[j][j] == 0.0 and nsing == n:
            nsing = j
        if nsing < n:
            wa1[j] = 0.0
    for j in range(nsing - 1, -1, -1):
        wa1[j] = wa1[j] / r[j][j]
        temp = wa1[j]
        for i in range(j):
            wa1[i] -= r[i][j] * temp
    x = [0.0] * n
    for j in range(n):
        x[ipvt[j]] = wa1[j]
    it = 0
    wa2 = [diag[j] * x[j] for j in range(n)]
    dxnorm = _enorm_list(wa2)
    fp = dxnorm - delta
    if fp <= 0.1 * delta:
        return 0.0, x
    parl = 0.0
    if nsing >= n:
        for j in range(n):
            lj = ipvt[j]
            wa1[j] = diag[lj] * _div(wa2[lj], dxnorm)
        for j in range(n):
            s = 0.0
            for i in range(j):
                s += r[i][j] * wa1[i]
            wa1[j] = (wa1[j] - s) / r[j][j]
        temp = _enorm_list(wa1)
        parl = _div(_div(fp / delta, temp), temp)
    for j in range(n):
        s = 0.0
        for i in range(j + 1):
            s += r[i][j] * qtb[i]
        wa1[j] = s / diag[ipvt[j]]
    gnorm = _enorm_list(wa1)
    paru = _div(gnorm, delta)
    if paru == 0.0:
        paru = _div(_DWARF, min(delta, 0.1))
    par = max(par, parl)
    par = min(par, paru)
    if par == 0.0:
        par = _div(gnorm, dxnorm)
    sdiag = [0.0] * n
    while True:
        it += 1
        if par == 0.0:
            par = max(_DWARF, 0.001 * paru)
        temp = math.sqrt(par)
        x = _qrsolv(r, ipvt, [temp * d for d in diag], qtb, sdiag)
        wa2 = [diag[j] * x[j] for j in range(n)]
        dxnorm = _enorm_list(wa2)
        temp = fp
        fp = dxnorm - delta
        if abs(fp) <= 0.1 * delta or (parl == 0.0 and fp <= temp and temp < 0.0) or it == 10:
            break
        for j in range(n):
            lj = ipvt[j]
            wa1[j] = diag[lj] * _div(wa2[lj], dxnorm)
        for j in range(n):
            wa1[j] = _div(wa1[j], sdiag[j])
            temp = wa1[j]
            for i in range(j + 1, n):
                wa1[i] -= r[i][j] * temp
        temp = _enorm_list(wa1)
        parc = _div(_div(fp / delta, temp), temp)
        if fp > 0.0:
            parl = max(parl, par)
        if fp < 0.0:
            paru = min(paru, par)
        par = max(parl, par + parc)
    return par, x


def lmder(fun, jac, x0, *, ftol: float = 1e-8, xtol: float = 1e-8, gtol: float = 1e-8, max_nfev=None,
          factor: float = 100.0, x_scale='jac'):
    """
    Minimise |fun(x)|^2 by MINPACK's lmder: what ``least_squares(fun, x0, jac, method='lm', x_scale=...)`` does.

    ``fun(x)`` -> residual (m,), ``jac(x)`` -> Jacobian (m, n), m >= n; ``max_nfev`` default 100 n (scipy's);
    ``x_scale`` 'jac' (MINPACK mode 1: scales from the Jacobian's column norms, updated) or positive numbers (mode 2:
    diag = 1 / x_scale, fixed), as scipy passes them.
    Returns (x (n,), info): info 1-4 converged (ftol / xtol / both / gtol), 5 max_nfev reached, 6-8 a tolerance
    below machine precision.  Raises ValueError for m < n or a non-finite initial residual (as scipy does).
    """
    x = np.array(x0, dtype=float).reshape(-1)
    n = x.size
    maxfev = 100 * n if max_nfev is None else int(max_nfev)
    fvec = np.asarray(fun(x), dtype=float).reshape(-1)
    if not np.all(np.isfinite(fvec)):
        raise ValueError('Residuals are not finite in the initial point.')
    m = fvec.size
    if n == 0 or m < n:
        raise ValueError(f"method 'lm' needs at least as many residuals ({m}) as variables ({n})")
    nfev = 1
    fnorm = _enorm(fvec)
    par = 0.0
    it = 1
    mode2 = not (isinstance(x_scale, str) and x_scale == 'jac')
    diag = np.broadcast_to(1.0 / np.asarray(x_scale, dtype=float), (n,)).copy() if mode2 else None
    delta = xnorm = 0.0
    while True:                                            # outer: a new Jacobian
        fjac = np.asarray(jac(x), dtype=float).reshape(m, n)
        ipvt, R, acnorm, qtf = _qrfac(fjac, fvec)
        if it == 1:
            if not mode2:
                diag = np.where(acnorm == 0.0, 1.0, acnorm)
            xnorm = _enorm(diag * x)
            delta = factor * xnorm
            if delta == 0.0:
                delta = factor
        r = R.tolist()
        ip, qt = ipvt.tolist(), qtf.tolist()
        gnorm = 0.0
        if fnorm != 0.0:
            acl = acnorm.tolist()
            for j in range(n):
                lj = ip[j]
                if acl[lj] != 0.0:
                    s = 0.0
                    for i in range(j + 1):
                        s += r[i][j] * (qt[i] / fnorm)
                    gnorm = max(gnorm, abs(s / acl[lj]))
        if gnorm <= gtol:
            return x, 4
        if not mode2:
            diag = np.maximum(diag, acnorm)
        dg = diag.tolist()
        while True:                                        # inner: steps until one is accepted
            par, stepl = _lmpar(r, ip, dg, qt, delta, par)
            step = -np.array(stepl)
            xt = x + step
            pnorm = _enorm(diag * step)
            if it == 1:
                delta = min(delta, pnorm)
            ft = np.asarray(fun(xt), dtype=float).reshape(-1)
            nfev += 1
            fnorm1 = _enorm(ft)
            actred = -1.0
            if 0.1 * fnorm1 < fnorm:
                actred = 1.0 - (fnorm1 / fnorm) ** 2
            wa3 = [0.0] * n
            for j in range(n):
                temp = stepl[ip[j]]
                for i in range(j + 1):
                    wa3[i] -= r[i][j] * temp
            temp1 = _enorm_list(wa3) / fnorm
            temp2 = (math.sqrt(par) * pnorm) / fnorm
            prered = temp1 ** 2 + temp2 ** 2 / 0.5
            dirder = -(temp1 ** 2 + temp2 ** 2)
            ratio = actred / prered if prered != 0.0 else 0.0
            if ratio <= 0.25:
                temp = 0.5 if actred >= 0.0 else _div(0.5 * dirder, dirder + 0.5 * actred)
                if 0.1 * fnorm1 >= fnorm or temp < 0.1:
                    temp = 0.1
                delta = temp * min(delta, pnorm / 0.1)
                par = par / temp
            elif par == 0.0 or ratio >= 0.75:
                delta = pnorm / 0.5
                par = 0.5 * par
            if ratio >= 1e-4:                              # successful step
                x = xt
                fvec = ft
                xnorm = _enorm(diag * x)
                fnorm = fnorm1
                it += 1
            info = 0
            small = abs(actred) <= ftol and prered <= ftol and 0.5 * ratio <= 1.0
            if small:
                info = 1
            if delta <= xtol * xnorm:
                info = 3 if small else 2
            if info:
                return x, info
            if nfev >= maxfev:
                return x, 5
            if abs(actred) <= _EPSMCH and prered <= _EPSMCH and 0.5 * ratio <= 1.0:
                return x, 6
            if delta <= _EPSMCH * xnorm:
                return x, 7
            if gnorm <= _EPSMCH:
                return x, 8
            if ratio >= 1e-4:
                break


# scipy's status of a MINPACK info (scipy.optimize._lsq.least_squares.FROM_MINPACK_TO_COMMON); 6-8 (a tolerance met
# to machine precision) scipy guards against up front, here they count as the ftol / xtol / gtol they refine
_STATUS = {1: 2, 2: 3, 3: 4, 4: 1, 5: 0, 6: 2, 7: 3, 8: 1}


def least_squares(fun, x0, jac, *, x_scale='jac', ftol: float = 1e-8, xtol: float = 1e-8, gtol: float = 1e-8,
                  max_nfev=None):
    """
    Return scipy's ``least_squares`` result for ``method='lm'``, computed by :func:`lmder` (no scipy import).

    ``fun`` (n,) -> (m,), ``jac`` (n,) -> (m, n) (callables), m >= n; ``x_scale`` 'jac' (scipy 1.17's default for
    'lm') or positive numbers.  Returns :class:`bearing_id.trf.Result` (x, cost = 0.5 |f|^2, fun, nfev, njev, status,
    success, message with scipy's meanings; nfev and njev count the calls as MINPACK does).
    """
    from .trf import Result
    count = {'f': 0, 'j': 0}

    def f(x):
        count['f'] += 1
        return fun(x)

    def j(x):
        count['j'] += 1
        return jac(x)
    x, info = lmder(f, j, x0, ftol=ftol, xtol=xtol, gtol=gtol, max_nfev=max_nfev, x_scale=x_scale)
    fv = np.asarray(fun(x), dtype=float).reshape(-1)
    return Result(x, 0.5 * float(fv @ fv), fv, count['f'], count['j'], _STATUS[info])
