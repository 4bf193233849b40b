"""
The fast transient-aware 1X fit equals its reference implementation (issue 13: every fast path keeps its reference).

Reference: ``bearing_id.signals.harmonics._transient_fit_reference`` (the first implementation, unchanged: variable
projection on the full (N nch,) residual) and ``_VarPro``.  The fast path (``_transient_fit``, ``_VarProFast``: reduced
coordinates from one QR, exponentials by products on a uniform grid, all screening candidates at once) must give the
same vectors, std, decaying components and residual to 1e-9 relative on windows that exercise every branch: steady
(nothing kept), a ringing mode beside 1X (kept, split candidates), a steady sub-synchronous line (rejected), noisy, a
short window (no coarse grid), jittered sample times (no uniform grid), and a simulated rig window after a speed ramp.
"""
import math

from bearing_id.signals import harmonics as signals
from bearing_id.signals.harmonics import _VarPro, _VarProFast, harmonic_vectors
import numpy as np
import pytest

FS = 10240.0
RTOL = 1e-9


def _rel(a, b) -> float:
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    if b.size == 0:
        return 0.0
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def _assert_same(x, angle, transients=3, **kw):
    fast = harmonic_vectors(x, angle, transients=transients, **kw)
    ref = harmonic_vectors(x, angle, transients=transients, transient_method='reference', **kw)
    assert fast.transient_rates.size == ref.transient_rates.size
    assert fast.transient_rejected == ref.transient_rejected
    for name in ('X', 'std', 'std_re', 'std_im', 'residual_rms', 'transient_rates', 'transient_X'):
        e = _rel(getattr(fast, name), getattr(ref, name))
        assert e <= RTOL, (name, e)
    assert np.max(np.abs(fast.offset - ref.offset)) <= RTOL * np.max(np.abs(ref.X))
    return ref


def _window(seed, modes, dur=1.5, noise=2e-7, speed_hz=35.0):
    """1X at ``speed_hz`` + decaying sinusoids [(f Hz, s 1/s, (2,) complex amplitude)] + white noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(dur * FS)) / FS
    angle = 0.3 + 2 * math.pi * speed_hz * t
    X = np.array([2e-5 * np.exp(0.4j), 1.5e-5 * np.exp(-1.1j)])
    x = np.real(np.outer(np.exp(1j * angle), X))
    for f, s, A in modes:
        x += np.real(np.outer(np.exp((-s + 2j * math.pi * f) * t), np.asarray(A) * np.exp(1j * seed)))
    return x + noise * rng.standard_normal(x.shape), angle, t


RINGING = [(33.0, 1.0, [1.5e-5, 1.5e-5j]), (32.6, 3.0, [8e-6, -8e-6j]), (103.0, 5.0, [3e-6, 2e-6])]


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_fast_fit_equals_reference_beside_ringing_modes(seed):
    ref = _assert_same(*_window(seed, RINGING)[:2], sample_rate=FS)
    assert ref.transient_rates.size >= 2          # the case has components to find


def test_the_plain_regression_kept_beside_the_components_is_the_plain_fit():
    """HarmonicFit.plain (set when components were kept) is what transients=0 returns, bit for bit; None otherwise."""
    x, angle, _ = _window(1, RINGING)
    fit = harmonic_vectors(x, angle, transients=3, sample_rate=FS)
    plain = harmonic_vectors(x, angle)
    assert fit.transient_rates.size and fit.plain is not None and plain.plain is None
    for name in ('X', 'std', 'std_re', 'std_im', 'offset', 'residual_rms'):
        assert np.array_equal(getattr(fit.plain, name), getattr(plain, name)), name
    assert not np.array_equal(fit.X, plain.X)
    steady = harmonic_vectors(*_window(7, [])[:2], transients=3, sample_rate=FS)
    assert steady.transient_rates.size == 0 and steady.plain is None


def test_fast_fit_equals_reference_on_a_steady_window():
    ref = _assert_same(*_window(7, [])[:2], sample_rate=FS)
    assert ref.transient_rates.size == 0


def test_fast_fit_equals_reference_on_a_noisy_window():
    x, angle, _ = _window(3, RINGING[:1], noise=3e-6)        # noise 15 % of 1X
    _assert_same(x, angle, sample_rate=FS)


def test_fast_fit_equals_reference_when_a_steady_line_is_rejected():
    ref = _assert_same(*_window(5, [(14.0, 0.0, [5e-6, 5e-6j])])[:2], transients=2, sample_rate=FS)
    assert ref.transient_rejected >= 1


def test_fast_fit_equals_reference_on_a_short_window_and_jittered_times():
    x, angle, t = _window(4, RINGING, dur=0.19)              # < TRANSIENT_MAX_POINTS samples: no coarse grid
    _assert_same(x, angle, sample_rate=FS)
    x, angle, t = _window(6, RINGING)
    tj = t + 2e-6 * np.random.default_rng(1).random(t.size)   # not a uniform grid: plain exponentials
    assert signals._uniform_step(tj) is None and signals._uniform_step(t) is not None
    ref = _assert_same(x, angle, t=tj)
    assert ref.transient_rates.size >= 1


def test_fast_fit_equals_reference_on_a_simulated_rig_window_after_a_ramp():
    """The rig simulator's response after a speed ramp (the rotor's own modes ringing), as window_vector fits it."""
    from bearing_id.config.params import load_rig
    from bearing_id.simulation.rig import simulate_run
    rig = load_rig()
    rec = simulate_run(rig, rig.simulation.runs[0], speeds_rpm=[1500, 2100], dwell=1.5, ramp=0.3)
    i0 = int(np.searchsorted(rec.t, 1.5 + 0.3 + 0.05))        # just after the ramp: ringing
    x, angle = rec.samples[i0:i0 + int(1.2 * rec.sample_rate)], rec.angle[i0:i0 + int(1.2 * rec.sample_rate)]
    _assert_same(x, angle, sample_rate=rec.sample_rate)


def test_reduced_variable_projection_has_the_reference_inner_products():
    """_VarProFast's reduced residual and Jacobian: r^T r, J^T J and J^T r of the full ones, and the same c1."""
    x, _, t = _window(2, RINGING, dur=0.4)
    angle = 0.3 + 2 * math.pi * 35.0 * t
    D = np.column_stack([np.ones(t.size), np.cos(angle), np.sin(angle)])
    ref, fast = _VarPro(x * 1e6, D, t), _VarProFast(x * 1e6, D, t)
    for p in (np.array([1.0, 2 * math.pi * 33.0]), np.array([1.0, 2 * math.pi * 33.0, 3.0, 2 * math.pi * 103.0]),
              np.array([0.2, 2 * math.pi * 34.9, 9.0, 2 * math.pi * 20.0, 4.0, 2 * math.pi * 60.0])):
        r0, J0, c0 = ref.evaluate(p)
        r1, J1, c1 = fast.evaluate(p)
        assert r1.size < r0.size
        assert _rel(r1 @ r1, r0 @ r0) <= RTOL
        assert _rel(J1.T @ J1, J0.T @ J0) <= RTOL
        assert _rel(J1.T @ r1, J0.T @ r0) <= RTOL
        assert _rel(c1, c0) <= RTOL
        np.testing.assert_allclose(fast.time_residual(p), r0.reshape(x.shape), rtol=0, atol=RTOL * np.abs(r0).max())
        # all screening candidates at once == one evaluation each
        cands = np.array([[0.5, 2 * math.pi * 31.0], [3.0, 2 * math.pi * 47.5], [15.0, 2 * math.pi * 88.0]])
        rss = fast.screen(p, cands)
        for k, (s, w) in enumerate(cands):
            rk = ref.evaluate(np.concatenate([p, [s, w]]), False)[0]
            assert _rel(rss[k], rk @ rk) <= RTOL


def test_uniform_grid_exponentials_equal_plain_ones():
    t = np.arange(15361) / FS - 0.25
    lam = np.array([-1.0 + 2j * math.pi * 33.0, -40.0 + 2j * math.pi * 300.0])
    z = signals._exp_outer(t, lam, signals._uniform_step(t))
    np.testing.assert_allclose(z, np.exp(np.outer(t, lam)), rtol=1e-12, atol=0)


def test_transient_method_is_checked():
    x, angle, _ = _window(0, [])
    with pytest.raises(ValueError, match='transient_method'):
        harmonic_vectors(x, angle, transients=1, sample_rate=FS, transient_method='slow')


@pytest.mark.parametrize('modes', [[], RINGING])
def test_gram_screen_equals_the_stacked_qr_screen(modes):
    """The screen by 2x2 Gram matrices equals its reference (one stacked QR per candidate), incl. a split candidate."""
    x, _, t = _window(4, modes, dur=0.5)
    angle = 0.3 + 2 * math.pi * 35.0 * t
    D = np.column_stack([np.ones(t.size), np.cos(angle), np.sin(angle)])
    vp = _VarProFast(x * 1e6, D, t)
    T = t[-1] - t[0]
    w0, w1 = 2 * math.pi * 33.0, 2 * math.pi * 32.6
    for p in (np.zeros(0), np.array([1.0, w0]), np.array([1.0, w0, 3.0, w1])):
        cands = [(sd / T, 2 * math.pi * (f + d / T)) for f in (33.0, 47.5, 103.0) for d in (-0.5, 0.0, 0.5)
                 for sd in (0.5, 3.0, 15.0)]
        assert _rel(vp.screen(p, cands), vp.screen_qr(p, cands)) <= RTOL
    p = np.array([1.0, 2 * math.pi * 33.0])
    same = [(1.0, 2 * math.pi * 33.0), (3.0, 2 * math.pi * 40.0)]     # the first lies in span(D0, E(p)): QR route
    assert _rel(vp.screen(p, same)[1:], vp.screen_qr(p, same)[1:]) <= RTOL
