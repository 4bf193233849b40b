"""
Harmonic vectors, steady windows and slow roll on synthetic signals with known truth.

References: signals built here with conventions.phasor_to_time (the phasor rule), the theoretical least-squares
variance sigma^2 (D^T D)^-1 checked against the empirical scatter over repeated noise draws, and the steady-window
rule written out sample by sample in plain Python.  Noise-free fits must return the truth within the rounding bound
of a backward-stable least-squares solve (:func:`_exact_tol`).  The transient-aware fit is in test_transient.py,
sub-synchronous lines in test_subsync.py.
"""
import math

from bearing_id.conventions import phasor_to_time
from bearing_id.signals.harmonics import harmonic_vectors, slow_roll_compensate, slow_roll_vector, whole_revolutions
from bearing_id.signals.windows import steady_windows, SteadyWindowTracker
import numpy as np
import pytest

FS = 10240.0
EPS = np.finfo(float).eps


def _exact_tol(x, angle, orders) -> float:
    """
    Return the error bound [unit of x] of noise-free harmonic vectors fitted to x (N, nch) on the rotor ``angle``.

    A backward-stable least-squares solve (Householder QR) with design matrix D (N, k) = [1, cos k angle, ...] errs
    by at most gamma kappa(D) |coef| with gamma = N k eps / (1 - N k eps) (Higham, Accuracy and Stability, ch. 20,
    worst-case constants; a zero residual); the data themselves carry rounding of relative size 2 eps (cos and the
    sum), which moves the coefficients by at most 2 eps |x| / sigma_min(D).  Twice the sum is allowed.
    """
    cols = [np.ones(angle.size)] + [f(k * angle) for k in orders for f in (np.cos, np.sin)]
    sv = np.linalg.svd(np.column_stack(cols), compute_uv=False)
    N, k = angle.size, len(cols)
    gamma = N * k * EPS / (1 - N * k * EPS)
    return 2 * (gamma * sv[0] / sv[-1] * np.max(np.abs(x)) * math.sqrt(k) + 2 * EPS * np.linalg.norm(x) / sv[-1])


def _signal(angle, phasors, offset):
    """Return offset + sum_k Re{X_k exp(j k angle)} per channel; phasors {k: (nch,) complex}."""
    x = np.zeros((angle.size, len(offset))) + np.asarray(offset)
    for k, Xk in phasors.items():
        for c, X in enumerate(Xk):
            x[:, c] += phasor_to_time(X, k * angle)
    return x


def test_known_phasors_with_offset_and_phase_convention():
    W = 2 * math.pi * 25.0                       # 1500 rpm
    t = np.arange(int(0.8 * FS)) / FS
    angle = 0.7 + W * t                          # keyphasor mark not at t = 0
    true = {1: np.array([3e-5 * np.exp(1j * 0.4), 2e-5 * np.exp(-1j * 2.0)]),
            2: np.array([4e-6 * np.exp(1j * 1.1), 1e-6j])}
    x = _signal(angle, true, offset=[5e-6, -2e-6])
    fit = harmonic_vectors(x, angle, orders=(1, 2))
    assert fit.X.shape == (2, 2)
    tol = _exact_tol(x[fit.i0:fit.i1], angle[fit.i0:fit.i1], (1, 2))
    np.testing.assert_allclose(fit.X[0], true[1], rtol=0, atol=tol)
    np.testing.assert_allclose(fit.X[1], true[2], rtol=0, atol=tol)
    np.testing.assert_allclose(fit.offset, [5e-6, -2e-6], rtol=0, atol=tol)
    assert np.all(fit.residual_rms < tol)
    # the phase convention: a peak of x at angle = -arg(X) (x = |X| cos(angle + arg X)); a complex exponential
    # and a product round a few times
    X = fit.X[0, 0]
    assert phasor_to_time(X, -np.angle(X)) == pytest.approx(abs(X), rel=8 * EPS)
    # unpacks as (X, std) per the contract
    X2, std = fit
    assert X2 is fit.X and std.shape == (2, 2)


def test_whole_revolution_trim():
    W = 2 * math.pi * 17.3
    n = 5000
    angle = W * np.arange(n) / FS
    i0, i1, n_rev = whole_revolutions(angle)
    assert n_rev == int((angle[-1] + W / FS) // (2 * math.pi))
    # the kept samples cover n_rev turns to within one sample
    covered = angle[i1 - 1] - angle[0] + W / FS
    assert abs(covered - 2 * math.pi * n_rev) <= W / FS
    with pytest.raises(ValueError, match='revolution'):
        harmonic_vectors(np.zeros((100, 1)), angle[:100])


def test_slowly_varying_speed_exact_when_regressed_on_angle():
    # speed ramps 1500 -> 1590 rpm (6 %) over the window; the signal is locked to the rotor angle
    t = np.arange(int(1.0 * FS)) / FS
    W0, W1 = 2 * math.pi * 25.0, 2 * math.pi * 26.5
    angle = W0 * t + 0.5 * (W1 - W0) * t**2 / t[-1]
    true = {1: np.array([1e-5 * np.exp(1j * 2.5)]), 3: np.array([2e-6 * np.exp(-1j * 0.3)])}
    x = _signal(angle, true, offset=[1e-6])
    fit = harmonic_vectors(x, angle, orders=(1, 3))
    tol = _exact_tol(x[fit.i0:fit.i1], angle[fit.i0:fit.i1], (1, 3))
    np.testing.assert_allclose(fit.X[0, 0], true[1][0], rtol=0, atol=tol)
    np.testing.assert_allclose(fit.X[1, 0], true[3][0], rtol=0, atol=tol)
    # regressing on omega t (mean speed) instead would be badly off: the method matters
    W = (angle[-1] - angle[0]) / t[-1]
    naive = harmonic_vectors(x, W * t, orders=(1, 3))
    assert abs(naive.X[0, 0] - true[1][0]) > 0.1 * abs(true[1][0])


def test_std_matches_empirical_scatter():
    rng = np.random.default_rng(7)
    W = 2 * math.pi * 30.0
    t = np.arange(2048) / FS
    angle = W * t
    X1 = 2e-5 * np.exp(1j * 0.9)
    clean = _signal(angle, {1: np.array([X1])}, offset=[0.0])
    sigma = 2e-6
    est, pred = [], []
    for _ in range(400):
        fit = harmonic_vectors(clean + sigma * rng.standard_normal(clean.shape), angle)
        est.append(fit.X[0, 0])
        pred.append(fit.std[0, 0])
    est = np.array(est)
    emp = math.sqrt(np.mean(np.abs(est - X1) ** 2))
    # theory for white noise over whole revolutions: sqrt(E|dX|^2) = sigma sqrt(4 / N)
    n_used = harmonic_vectors(clean, angle).i1
    assert np.mean(pred) == pytest.approx(sigma * math.sqrt(4.0 / n_used), rel=0.02)
    # 400 repeats: the empirical std has ~3.5 % sampling scatter; allow 12 %
    assert emp == pytest.approx(np.mean(pred), rel=0.12)
    # Re and Im separately
    assert np.std(est.real) == pytest.approx(sigma * math.sqrt(2.0 / n_used), rel=0.15)


def test_nonfinite_refused_or_dropped():
    W = 2 * math.pi * 20.0
    angle = W * np.arange(4096) / FS
    x = _signal(angle, {1: np.array([1e-5, 2e-5j])}, offset=[0.0, 0.0])
    x[100, 0] = np.nan
    x[200, 1] = np.inf
    with pytest.raises(ValueError, match='2 non-finite'):
        harmonic_vectors(x, angle)
    fit = harmonic_vectors(x, angle, nonfinite='drop')
    assert fit.n_dropped == 2
    ok = np.all(np.isfinite(x), axis=1)[fit.i0:fit.i1]
    tol = _exact_tol(x[fit.i0:fit.i1][ok], angle[fit.i0:fit.i1][ok], (1,))
    np.testing.assert_allclose(fit.X[0], [1e-5, 2e-5j], rtol=0, atol=tol)
    bad_angle = angle.copy()
    bad_angle[5] = np.nan
    with pytest.raises(ValueError, match='angle'):
        harmonic_vectors(np.nan_to_num(x), bad_angle)


def test_wrapped_angle_is_unwrapped():
    W = 2 * math.pi * 20.0
    angle = W * np.arange(4096) / FS
    x = _signal(angle, {1: np.array([1e-5 * np.exp(0.3j)])}, offset=[0.0])
    fit = harmonic_vectors(x, np.mod(angle, 2 * math.pi))
    np.testing.assert_allclose(fit.X[0, 0], 1e-5 * np.exp(0.3j), rtol=0,
                               atol=_exact_tol(x[fit.i0:fit.i1], angle[fit.i0:fit.i1], (1,)))


def test_steady_windows_on_step_schedule_with_ramp():
    # 1 s at 1000 rpm, 0.5 s ramp to 1500 rpm, 1 s at 1500 rpm, 0.2 s at 1600 rpm (too short)
    pieces = [np.full(int(FS), 1000.0), np.linspace(1000, 1500, int(0.5 * FS)), np.full(int(FS), 1500.0),
              np.full(int(0.2 * FS), 1600.0)]
    speed = np.concatenate(pieces)
    t = np.arange(speed.size) / FS
    speed_noisy = speed * (1 + 1e-4 * np.random.default_rng(1).standard_normal(speed.size))
    w = steady_windows(t, speed_noisy, tol_rel=0.005, min_duration=0.5)
    assert len(w) == 2
    (a0, a1), (b0, b1) = w
    n1 = int(FS)
    assert a0 == 0 and abs(a1 - n1) <= int(0.005 * 1000 / 500 * 0.5 * FS) + 1  # ends where the ramp leaves the band
    assert np.all(np.abs(speed[b0:b1] - 1500) <= 0.005 * 1500)
    assert (b1 - b0) / FS >= 0.99
    # NaN speeds break windows
    s2 = speed_noisy.copy()
    s2[n1 // 2] = np.nan
    w2 = steady_windows(t, s2, tol_rel=0.005, min_duration=0.4)
    assert all(not (i0 <= n1 // 2 < i1) for i0, i1 in w2)


def test_slow_roll_estimate_and_compensation():
    # runout: a constant 1X vector at the probe; dynamic response grows with speed^2 (below the first critical)
    runout = 3e-6 * np.exp(1j * 1.2)
    dyn_per_w2 = 1e-9 * np.exp(-1j * 0.5)
    segs = []
    angle0 = 0.0
    for rpm in (200.0, 1500.0):
        W = rpm * 2 * math.pi / 60
        n = int(1.0 * FS)
        ang = angle0 + W * np.arange(n) / FS
        angle0 = ang[-1] + W / FS
        segs.append((np.full(n, W), ang, runout + dyn_per_w2 * W**2))
    speed = np.concatenate([s[0] for s in segs])
    angle = np.concatenate([s[1] for s in segs])
    x = np.concatenate([phasor_to_time(s[2], s[1]) for s in segs])[:, None]
    t = np.arange(speed.size) / FS
    sr = slow_roll_vector(x, angle, t, speed, max_speed=300 * 2 * math.pi / 60)
    W_sr = 200 * 2 * math.pi / 60
    i = int(FS)
    tol_sr = _exact_tol(x[sr.i0:sr.i1], angle[sr.i0:sr.i1], (1,))
    np.testing.assert_allclose(sr.X[0, 0], runout + dyn_per_w2 * W_sr**2, rtol=0, atol=tol_sr)
    hi = harmonic_vectors(x[i:], angle[i:])
    comp = slow_roll_compensate(hi.X, sr.X)
    W = 1500 * 2 * math.pi / 60
    # vector subtraction removes the runout; what is left is the dynamic part minus its small slow-roll share
    tol = tol_sr + _exact_tol(x[i:][hi.i0:hi.i1], angle[i:][hi.i0:hi.i1], (1,))
    np.testing.assert_allclose(comp[0, 0], dyn_per_w2 * (W**2 - W_sr**2), rtol=0, atol=tol)
    with pytest.raises(ValueError, match='no steady window'):
        slow_roll_vector(x, angle, t, speed, max_speed=10.0)


# ------------------------------------------------------------------------------------------------ steady windows
def _windows_by_the_rule(speed, tol_rel):
    """Return the steady windows of the documented rule, sample by sample (plain Python floats)."""
    out, i0 = [], None
    hi = lo = s = 0.0
    count = 0
    for i, v in enumerate(speed):
        v = float(v)
        if not math.isfinite(v):
            if i0 is not None:
                out.append((i0, i))
                i0 = None
            continue
        if i0 is not None:
            h, lw, ss = max(hi, v), min(lo, v), s + v
            if h - lw > tol_rel * max(abs(ss / (count + 1)), 1e-300):
                out.append((i0, i))
                i0 = None
            else:
                hi, lo, s, count = h, lw, ss, count + 1
                continue
        i0, hi, lo, s, count = i, v, v, v, 1
    if i0 is not None:
        out.append((i0, i0 + count))
    return out


def test_tracker_equals_the_rule_in_any_chunking():
    rng = np.random.default_rng(5)
    parts = []
    for level in (50.0, 80.0, 120.0):                    # dwells, ramps, noise, gaps
        parts += [level * (1 + 1e-3 * rng.standard_normal(6000)), np.linspace(level, level + 30.0, 2500)]
    speed = np.concatenate(parts)
    speed[[100, 7000, 7001, 15000]] = np.nan
    speed[9000:9010] = np.inf
    want = _windows_by_the_rule(speed, 0.005)
    assert len(want) > 100
    for chunks in ([speed.size], [1, 7, 1000, 5, 33000], list(rng.integers(1, 3000, 60))):
        tr = SteadyWindowTracker(0.005)
        got, o = [], 0
        for c in chunks:
            got += tr.feed(speed[o:o + c])
            o += c
        got += tr.feed(speed[o:]) + tr.close()
        assert got == want
