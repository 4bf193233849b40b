"""
Issue 11 look-alikes (diagnose side): verdicts and parameters against the simulator's hidden truth.

Usage (from the repository root)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/issue11_lookalikes.py {plan|test} CASE [CASE ...]

plan = the packaged plan (runs A and B, 600 ... 3000 rpm in 9 dwells of 2 s, 1 % noise); test = run A, 1.5 s slow
roll at 200 rpm + 1 s dwells at 800, 1200, 1600, 2400, 2800 rpm (the proof tests' schedule).  Truth bearings: the
rig's truth factors (viscosity x1.25, clearance x0.8), short bearing, or with the prefix ``fin_`` finite-length
(L/D = 1) bearings from the direct Reynolds solver (bearings.finite.reynolds, not the table the fitting side uses).
Cases: clean, pair (x/y pair turned 11.7 deg, x gain 1.083), support_K (pedestal under bearing 2, vertical, k = K,
c = 60 N s/m, m = 0.86 kg), supportx1 (bearing 1, horizontal, 3e5 N/m, 40 N s/m, 0.5 kg), two (support_2e5 + 3 um
runout on p6y), whirl (onset 2000 rpm), whirl_top (whirl only at the top speed: in one held-out fold only).
"""
import math
import sys
import time

from bearing_id.config.params import load_rig
from bearing_id.conventions import rpm_to_rad_s
from bearing_id.diagnose import diagnose
from bearing_id.identify import identify
from bearing_id.identify.harmonics import from_recordings
from bearing_id.rotor import supports
from bearing_id.rotor.assembly import RotorModel
from bearing_id.simulation import effects as te, rig as rigmod

TEST_SPEEDS = (800, 1200, 1600, 2400, 2800)


def direct_finite_fn(rig, vf=1.25, cf=0.8):
    from bearing_id.bearings.finite import reynolds
    loads = supports.static_loads(rig)
    cache = {}

    def fn(W):
        if W not in cache:
            cache[W] = {b.node: (lambda s: (s.K.copy(), s.C.copy()))(
                reynolds(b.diameter, b.length, b.clearance * cf, b.viscosity * vf, loads[b.node], W))
                for b in rig.bearings}
        return {n: (K.copy(), C.copy()) for n, (K, C) in cache[W].items()}
    return fn


def case(name, plan):
    nominal = load_rig()
    matched = rigmod.with_truth(nominal, viscosity_factor=(1.0, 1.0), clearance_factor=(1.0, 1.0))
    bfn = None
    if name.startswith('fin_'):
        bfn, name = direct_finite_fn(nominal), name[4:]
    if name == 'clean':
        return nominal, [], {}, bfn
    if name == 'pair':
        return (nominal, [te.ProbePairOrientation(6, math.radians(11.7), 1.083, 1.0)],
                {'angle_deg': 11.7, 'gain_x': 1.083, 'gain_y': 1.0}, bfn)
    if name.startswith('support_'):
        k = float(name.split('_')[1])
        return (nominal, [te.SupportFlexibility(10, k=(None, k), c=(0.0, 60.0), mass=(0.0, 0.86))],
                {'k_y': k, 'c_y': 60.0, 'm_y': 0.86}, bfn)
    if name == 'supportx1':
        return (nominal, [te.SupportFlexibility(2, k=(3e5, None), c=(40.0, 0.0), mass=(0.5, 0.0))],
                {'k_x': 3e5, 'c_x': 40.0, 'm_x': 0.5}, bfn)
    if name == 'two':
        return (nominal, [te.SupportFlexibility(10, k=(None, 2e5), c=(0.0, 60.0), mass=(0.0, 0.86)),
                          te.ProbeRunout('p6y', 3e-6, 2.1)],
                {'k_y': 2e5, 'c_y': 60.0, 'm_y': 0.86, 'runout': 3e-6}, bfn)
    if name == 'whirl':
        return matched, [te.OilWhirl(10, 2000.0, 0.45, 0.5)], {'ratio': 0.45, 'onset_rpm': 2000.0}, bfn
    if name == 'whirl_top':
        return matched, [te.OilWhirl(10, 2850.0 if plan == 'plan' else 2600.0, 0.45, 0.5)], {}, bfn
    raise SystemExit(f'unknown case {name}')


def recordings(truth, effects, plan, bfn):
    kw = {'bearing_fn': bfn} if bfn is not None else {}
    if plan == 'test':
        sched = [rigmod.Segment(float(rpm_to_rad_s(200)), 1.5)] + rigmod.step_schedule(TEST_SPEEDS, 1.0)
        return [rigmod.simulate(truth, truth.simulation.runs[0], sched, effects=effects, **kw)]
    return rigmod.simulate_plan(truth, effects=effects, **kw)


def main(plan, names):
    for name in names:
        truth, effects, want, bfn = case(name, plan)
        recs = recordings(truth, effects, plan, bfn)
        rig = load_rig()
        res = identify('physical', RotorModel.from_params(rig), rig, from_recordings(recs))
        misfit = any('MODEL MISFIT' in n for n in res[0].notes)
        t = time.time()
        d = diagnose(recs, rig)
        nf = d.noise_floor or {}
        print(f'== {name} ({plan}): identify physical (short): {"MODEL MISFIT" if misfit else "fits"}; '
              f'diagnose {time.time() - t:.0f} s, verdict {d.verdict}; noise floor chi2/dof nominal '
              f'{nf.get("chi2_dof_nominal", math.nan):.3g} -> final {nf.get("chi2_dof_after", math.nan):.3g} '
              f'(limit {nf.get("threshold", math.nan):.3g}); parameters fitted at {nf.get("parameters_fitted_at")}')
        for e in d.effects:
            p, sd, und = e['parameters'], e['std'], set(e.get('undetermined', []))
            row = []
            for k, v in p.items():
                if k in want:
                    row.append(f'{k} {v:.4g} (truth {want[k]:.4g}, {100 * (v / want[k] - 1):+.1f} %, '
                               f'1s {sd.get(k, math.nan):.2g}{", UNDETERMINED" if k in und else ""})')
                elif k.startswith(('viscosity_factor', 'clearance_factor')):
                    row.append(f'{k} {v:.3f}')
            print(f'   {e["effect"]}: ' + '; '.join(row))
        print('   bearing factors: viscosity ' + ', '.join(f'x{v:.3f}' for v in d.bearing_factors['viscosity_factor'])
              + '; clearance ' + ', '.join(f'x{v:.3f}' for v in d.bearing_factors['clearance_factor']))
        for h in d.hypotheses:
            if h['effect'] == 'oil_whirl' and h['step'] == 0:
                print(f'   oil_whirl hypothesis: validated {h["validated"]}, held-out chi2 reduction '
                      f'{h["heldout_reduction"]:+.2f}')
        sys.stdout.flush()


if __name__ == '__main__':
    main(sys.argv[1], sys.argv[2:])
