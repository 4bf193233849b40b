"""
Where a residual no candidate explains lives, what it resembles, and what measurement would tell candidates apart.

"Unexplained" is an answer with content (issue 24 item 3).  Given the observations and a fitted model (a
:class:`~bearing_id.diagnose.selection.Fit` on a :class:`~bearing_id.diagnose.predict.Problem`), the residual of every
window, r = X_measured - X_predicted (complex harmonic vectors [m]), is measured against its 1-sigma ``s`` (noise
floor and model tolerance, :func:`bearing_id.diagnose.locate.sigma`) as chi-square terms z = |r|^2 / s^2, and
summarised:

* **harmonic order**: the share of sum z at 1X, 2X, 3X and sub-synchronous;
* **probe**: the share per probe;
* **speeds**: where it lives, the speeds with an entry beyond ``threshold`` sigma and beyond ``PEAK_SHARE`` of the
  largest significance (the bearing nuisance refitted under "none" spreads a few sigma of a local residual to its
  neighbours; that is not where it lives); *speed-local* when those speeds are an inner part of the range (neither
  the lowest nor the highest recorded, spanning at most half of it); otherwise the growth of the dominant order's
  residual with speed, the exponent p of |r| ~ speed^p (least squares in log-log over the windows above slow roll);
* **runs**: whether the dominant order's residual is the same in every run (the difference between two runs at one
  speed within ``threshold`` sigma of their combined noise while the residual itself is beyond it: a source that
  does not follow the known excitation) or changes with the run (the response to the known forces is mispredicted);
* **whirl**: for the first x/y probe pair, the share of the dominant order's residual power whirling forward,
  |r_x + j r_y|^2 / (|r_x + j r_y|^2 + |r_x - j r_y|^2) (:func:`bearing_id.conventions.whirl_direction`'s split);
* **slow roll**: whether it is present below ``slow_roll_rpm`` (runout and bow are; unbalance is not).

From these it says what the residual resembles (plain rules from rotordynamics: Muszynska, *Rotordynamics*, 2005, ch.
6-8 for rub and whirl; Bently & Hatch, *Fundamentals of Rotating Machinery Diagnostics*, 2002, for slow roll, runout,
crack 2X near half a critical speed and misalignment) and what measurement would tell the candidates apart -- what
this recording set lacks (slow roll, a second probe station, a run with the unbalance moved, an x/y pair, speeds
through half a critical speed), as ``bearing-id design`` does for identification.  DC (probe gap) is not measured by
this diagnosis (gap voltages are unknown offsets): a rub's DC push is not looked for.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .locate import xy_pair

SLOW_ROLL_RPM = 400.0
PEAK_SHARE = 0.25       # a speed holds the residual when its significance reaches this share of the largest


@dataclass
class Signature:
    """
    Where a residual lives (see the module docstring).  Shares are fractions of the residual's chi-square.

    orders {label: share}; probes {name: share}; speeds_rpm: speeds with an entry beyond the threshold; speed_local;
    speed_exponent: p of |r| ~ speed^p for the dominant order (None: too few speeds); runs: 'the same in every run',
    'changes with the run' or None (one run, or no speed in two runs); forward_share (None: no x/y pair);
    slow_roll: True / False / None (not recorded); n_stations: probe stations (nodes); significant: entries beyond
    the threshold; resembles, measure_next: sentences.
    """

    orders: dict
    probes: dict
    speeds_rpm: list
    speed_local: bool
    speed_exponent: float | None
    runs: str | None
    forward_share: float | None
    slow_roll: bool | None
    n_stations: int
    significant: int
    threshold: float
    resembles: list = field(default_factory=list)
    measure_next: list = field(default_factory=list)

    @property
    def dominant(self) -> str:
        """Return the harmonic order holding the largest share of the residual ('1X', '2X', ..., 'sub-synchronous')."""
        return max(self.orders, key=self.orders.get) if self.orders else ''

    def where(self) -> str:
        """Return one sentence: where the residual lives."""
        if not self.significant:
            return f'no residual entry is beyond {self.threshold:g} sigma'
        ords = ', '.join(f'{k} {v:.0%}' for k, v in sorted(self.orders.items(), key=lambda kv: -kv[1]) if v >= 0.05)
        prb = ', '.join(f'{k} {v:.0%}' for k, v in sorted(self.probes.items(), key=lambda kv: -kv[1]) if v >= 0.05)
        sp = ', '.join(f'{s:.0f}' for s in self.speeds_rpm)
        parts = [f'the residual lives at {ords} (share of its chi-square)', f'on probes {prb}',
                 f"{'only ' if self.speed_local else ''}at {sp} rpm"
                 + (' (speed-local)' if self.speed_local else '')]
        if self.speed_exponent is not None and not self.speed_local:
            p = self.speed_exponent
            how = 'about constant with speed' if abs(p) < 0.5 else ('growing' if p > 0 else 'falling') + ' with speed'
            parts.append(f'the {self.dominant} residual {how} (|r| ~ speed^{p:.1f})')
        if self.runs:
            parts.append(f'{self.dominant} {self.runs}')
        if self.forward_share is not None:
            fs = self.forward_share
            how = 'forward' if fs >= 0.75 else 'backward' if fs <= 0.25 else 'along a line (forward and backward alike)'
            parts.append(f'{self.dominant} whirling {how} ({fs:.0%} forward)')
        if self.slow_roll is not None:
            parts.append('present at slow roll' if self.slow_roll else 'absent at slow roll')
        return '; '.join(parts)

    def sentences(self, lead: str = 'unexplained') -> list:
        """Return the sentences a diagnosis prints: where (after ``lead``), what it resembles, what to measure."""
        out = [f'{lead}: ' + self.where()]
        if self.resembles:
            out.append('it resembles ' + '; or '.join(self.resembles))
        if self.measure_next:
            out.append('to tell these apart: ' + '; '.join(self.measure_next))
        return out

    def as_dict(self) -> dict:
        return {'orders': self.orders, 'probes': self.probes, 'speeds_rpm': self.speeds_rpm,
                'speed_local': self.speed_local, 'speed_exponent': self.speed_exponent, 'runs': self.runs,
                'forward_share': self.forward_share, 'slow_roll': self.slow_roll, 'n_stations': self.n_stations,
                'significant': self.significant, 'resembles': self.resembles, 'measure_next': self.measure_next}


def _residuals(prob, f, pred=None):
    """
    Return per window: (residual (n_orders, nch), sigma (n_orders, nch), sub residual (nch,) or None, its sigma).

    ``pred``: fit ``f``'s prediction by window if the caller has it (``Problem.prediction_by_window``).
    """
    if pred is None:
        pred = prob.prediction_by_window(f.theta, f.effects, f.nls, f.lin)
    out = []
    for k, w in enumerate(prob.obs.windows):
        S = prob.sig[prob.slices[k]].reshape(w.X.shape)
        rs = ss = None
        if prob.has_sub and w.X_sub is not None:
            rs = w.X_sub - f.sub_pred.get(k, 0.0)
            ss = np.maximum(w.std_sub, 1e-15)
        out.append((w.X - pred[k], S, rs, ss))
    return out


def _run_relation(prob, res, o: int, threshold: float) -> str | None:
    """Return 'the same in every run' / 'changes with the run' for order index ``o`` (None: no speed has two runs)."""
    by_speed: dict = {}
    for k, w in enumerate(prob.obs.windows):
        by_speed.setdefault(round(w.rpm), []).append(k)
    same = diff = 0
    for ks in by_speed.values():
        recs = {}
        for k in ks:
            recs.setdefault(prob.obs.windows[k].rec, k)
        ks = list(recs.values())
        for a in range(len(ks)):
            for b in range(a + 1, len(ks)):
                ra, sa = res[ks[a]][0][o], res[ks[a]][1][o]
                rb, sb = res[ks[b]][0][o], res[ks[b]][1][o]
                if ra.shape != rb.shape:
                    continue
                big = max(np.max(np.abs(ra) / sa), np.max(np.abs(rb) / sb))
                if big < threshold:
                    continue
                d = np.max(np.abs(ra - rb) / np.sqrt(sa ** 2 + sb ** 2))
                if d < threshold:
                    same += 1
                else:
                    diff += 1
    if not same and not diff:
        return None
    return 'the same in every run' if same >= diff else 'changes with the run'


def residual_signature(prob, f, *, threshold: float = 3.0, slow_roll_rpm: float = SLOW_ROLL_RPM,
                       pred=None) -> Signature:
    """
    Return the :class:`Signature` of fit ``f``'s residual on problem ``prob`` (see the module docstring).

    ``pred``: ``f``'s prediction by window when the caller has computed it (else it is computed here).
    """
    obs = prob.obs
    res = _residuals(prob, f, pred)
    labels = [f'{o:g}X' for o in obs.orders]
    orders = dict.fromkeys(labels, 0.0)
    probes: dict = {}
    peak: dict = {}            # speed [rpm] above slow roll -> largest significance there
    n_sig = 0
    slow = None
    stations = set()
    for k, w in enumerate(obs.windows):
        R, S, rs, ss = res[k]
        z = np.abs(R) ** 2 / S ** 2
        names = [p.name for p in obs.probes(w.rec)]
        stations.update(p.node for p in obs.probes(w.rec))
        for o, lab in enumerate(labels):
            orders[lab] += float(np.sum(z[o]))
        for c, name in enumerate(names):
            probes[name] = probes.get(name, 0.0) + float(np.sum(z[:, c]))
        top = float(np.max(np.sqrt(z)))
        n_sig += int(np.sum(z >= threshold ** 2))
        if rs is not None:
            zs = np.abs(rs) ** 2 / ss ** 2
            orders['sub-synchronous'] = orders.get('sub-synchronous', 0.0) + float(np.sum(zs))
            for c, name in enumerate(names):
                probes[name] += float(zs[c])
            top = max(top, float(np.max(np.sqrt(zs))))
            n_sig += int(np.sum(zs >= threshold ** 2))
        if w.rpm < slow_roll_rpm:
            slow = bool(slow) or top >= threshold
        else:
            peak[round(w.rpm)] = max(peak.get(round(w.rpm), 0.0), top)
    tot = sum(orders.values()) or 1.0
    orders = {k: v / tot for k, v in orders.items()}
    ptot = sum(probes.values()) or 1.0
    probes = {k: v / ptot for k, v in probes.items()}
    dom = max(orders, key=orders.get)
    o = labels.index(dom) if dom in labels else 0
    # growth with speed of the dominant order (windows above slow roll)
    rpm = np.array([w.rpm for w in obs.windows])
    amp = np.array([np.sqrt(np.mean(np.abs(res[k][0][o]) ** 2)) for k in range(len(obs.windows))])
    keep = (rpm >= slow_roll_rpm) & (amp > 0)
    exponent = None
    if len(set(np.round(rpm[keep]))) >= 3:
        exponent = float(np.polyfit(np.log(rpm[keep]), np.log(amp[keep]), 1)[0])
    all_rpm = sorted(peak)
    big = max(peak.values(), default=0.0)
    sp = sorted(k for k, v in peak.items() if v >= threshold and v >= PEAK_SHARE * big)
    local = bool(sp and len(all_rpm) >= 4 and sp[0] > all_rpm[0] and sp[-1] < all_rpm[-1]
                 and (sp[-1] - sp[0]) <= 0.5 * (all_rpm[-1] - all_rpm[0]))
    runs = _run_relation(prob, res, o, threshold) if len({w.rec for w in obs.windows}) > 1 else None
    fwd = None
    pair = xy_pair(obs.probes(obs.windows[0].rec)) if obs.windows else None
    if pair is not None:
        pf = pb = 0.0
        for k, w in enumerate(obs.windows):
            if xy_pair(obs.probes(w.rec)) != pair:
                continue
            rx, ry = res[k][0][o, pair[0]], res[k][0][o, pair[1]]
            pf += abs(rx + 1j * ry) ** 2
            pb += abs(rx - 1j * ry) ** 2
        fwd = float(pf / (pf + pb)) if pf + pb > 0 else None
    sgn = Signature(orders=orders, probes=probes, speeds_rpm=sp, speed_local=local, speed_exponent=exponent,
                    runs=runs, forward_share=fwd, slow_roll=slow, n_stations=len(stations), significant=n_sig,
                    threshold=float(threshold))
    sgn.resembles, sgn.measure_next = _readings(sgn, n_runs=len({w.rec for w in obs.windows}))
    return sgn


def _readings(s: Signature, n_runs: int) -> tuple[list, list]:
    """Return (what the signature resembles, what measurement would tell the candidates apart): plain rules."""
    if not s.significant:
        return [], []
    dom = s.dominant
    like, meas = [], []
    if dom == 'sub-synchronous':
        like.append('a sub-synchronous source: oil whirl or whip (forward, 0.4-0.5X, above an onset speed) or a rub '
                    '(backward or fractional 1/2X, 1/3X where the orbit reaches a clearance)')
    elif dom != '1X':
        like.append(f'a {dom} source beyond the fitted candidates: a crack breathing with the orbit rather than the '
                    f'sag (its harmonics then change with the run), a rub (harmonics where the orbit reaches a '
                    f'clearance), a coupling or a non-circular journal')
        if dom == '2X':
            meas.append('speeds through half and a third of each critical speed (a crack under its sag peaks at '
                        'both, its 3X beside its 2X; a coupling 2X has no 3X)')
    else:
        if s.speed_local:
            like.append('a speed-local 1X change: a rub where the orbit is largest, or a resonance of a part the model '
                        'lacks (a support or casing mode) at those speeds')
        if s.runs == 'changes with the run':
            like.append('a mispredicted response to the known forces: bearings, supports or a stiffness the model '
                        'gets wrong where the residual is largest')
        elif s.runs == 'the same in every run':
            like.append('a 1X source that does not follow the known excitation: ' + (
                'runout or a bow (present at slow roll)' if s.slow_roll else
                'a residual unbalance or a bow (growing with speed), or a rub'))
    if s.slow_roll is None:
        meas.append('a slow-roll run (runout, bow and the harmonics of a crack under its sag are present at slow '
                    'roll, unbalance is not)')
    if s.n_stations < 2:
        meas.append('a second probe station (locates the source along the shaft)')
    if n_runs < 2 or s.runs is None:
        meas.append('a run with the unbalance moved (a force the model lacks stays, a mispredicted response changes)')
    if s.forward_share is None:
        meas.append('an x/y probe pair (forward vs backward whirl)')
    return like, meas


__all__ = ['Signature', 'residual_signature']
