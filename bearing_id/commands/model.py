"""``bearing-id model``: the rotor-bearing model of a params file — natural frequencies, critical speeds, stability
threshold, bearing coefficients vs speed, Campbell diagram, and the Table-2 model-updating table.

Prints tables (rpm, Hz, N/m, N s/m) and writes ``campbell.png``, ``coefficients.png`` and ``model.json`` (SI units:
rad/s, N/m, N s/m, plus rpm/Hz copies for people) into ``--out``.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from ..conventions import COEFF_ORDER, rad_s_to_rpm, rpm_to_rad_s
from ..params import ParamError, load_rig

TWO_PI = 2.0 * math.pi


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("model", help="natural frequencies, critical speeds, stability, bearing coefficients, "
                                     "Campbell diagram and model updating of a rig",
                       description="Analyse the FE rotor-bearing model described by --params: free-free and "
                                   "on-bearing natural frequencies, critical speeds, the stability threshold (oil "
                                   "whip), bearing coefficients vs speed, a Campbell diagram, and the paper's "
                                   "Table-2 model updating against modal_test.measured_hz.")
    p.add_argument("--params", help="rig YAML (default: the packaged params/rig.yaml)")
    p.add_argument("--out", default="out/model", help="directory for campbell.png, coefficients.png, model.json "
                                                      "(default out/model)")
    p.add_argument("--max-rpm", type=float, default=6000.0,
                   help="upper end of the speed range for Campbell, critical speeds and stability [rpm] "
                        "(default 6000, the rig's maximum)")
    p.add_argument("--speeds", help="comma-separated speeds [rpm] for the coefficient and mode tables "
                                    "(default: simulation.speeds_rpm)")
    p.add_argument("--modes", type=int, default=6, help="number of modes to report (default 6)")
    p.add_argument("--no-update", action="store_true", help="skip the model updating (Table 2)")
    return p


def _speeds(args, rig):
    if args.speeds:
        try:
            v = [float(s) for s in args.speeds.split(",") if s.strip()]
        except ValueError:
            raise ParamError(f"--speeds must be comma-separated rpm values, got {args.speeds!r}") from None
    elif rig.simulation is not None:
        v = list(rig.simulation.speeds_rpm)
    else:
        v = list(np.linspace(args.max_rpm / 10, args.max_rpm, 10))
    if not v or any(s <= 0 for s in v):
        raise ParamError("--speeds: every speed must be > 0 rpm (no hydrodynamic film at standstill)")
    return v


def analyse(rig, speeds_rpm, max_rpm=6000.0, n_modes=6, update=True) -> dict:
    """Everything the command prints, as a dict (SI, with rpm/Hz copies)."""
    from .. import bearings
    from ..bearings import stability
    from ..rotor.assembly import RotorModel, static_bearing_loads
    from ..rotor.modal import campbell, critical_speeds, damped_modes, free_free_frequencies

    model = RotorModel.from_params(rig)
    bfn = bearings.bearing_fn(rig)
    out: dict = {"rig": rig.name, "mass_kg": model.mass,
                 "static_loads_N": {str(k): v for k, v in static_bearing_loads(model).items()}}
    ff = free_free_frequencies(model, 4)
    out["free_free_hz"] = (ff / TWO_PI).tolist()
    rows = []
    for rpm in speeds_rpm:
        W = float(rpm_to_rad_s(rpm))
        co = bfn(W)
        m = damped_modes(model, W, co, n_modes)
        rows.append({"speed_rpm": rpm, "speed": W,
                     "bearings": {str(n): {"K": np.asarray(k).tolist(), "C": np.asarray(c).tolist()}
                                  for n, (k, c) in co.items()},
                     "modes_hz": (m.frequency / TWO_PI).tolist(), "log_dec": m.log_dec.tolist(),
                     "whirl": list(m.whirl)})
    out["speeds"] = rows
    lo, hi = float(rpm_to_rad_s(max(50.0, max_rpm / 60))), float(rpm_to_rad_s(max_rpm))
    grid = np.linspace(lo, hi, 40)
    cb = campbell(model, grid, bfn, n_modes)
    out["campbell"] = {"speeds_rpm": rad_s_to_rpm(grid).tolist(), "frequency_hz": (cb.frequency / TWO_PI).tolist(),
                       "log_dec": cb.log_dec.tolist(), "whirl": cb.whirl.tolist()}
    crit = critical_speeds(model, bfn, (lo, hi), n_grid=40, n_modes=n_modes)
    out["critical_speeds_rpm"] = rad_s_to_rpm(crit).tolist() if crit.size else []
    zc = []
    for c in crit:   # damping ratio of the forward mode that crosses 1X there (amplification factor ~ 1 / (2 zeta))
        m = damped_modes(model, c, bfn(c), n_modes)
        k = int(np.argmin([abs(f - c) if w == "forward" else np.inf for f, w in zip(m.frequency, m.whirl)]))
        zc.append(float(m.damping_ratio[k]))
    out["critical_damping_ratio"] = zc
    thr = stability.threshold_speed(model, bfn, hi)
    out["stability_threshold_rpm"] = (float(rad_s_to_rpm(thr)) if thr is not None and np.isfinite(thr) else None)
    if update and rig.modal_test is not None and rig.modal_test.measured_hz:
        from ..updating import update_model
        res = update_model(rig, rig.modal_test.measured_hz, maxiter=1500)
        out["updating"] = {"table": res.table(), "factors": res.factors, "initial_hz": res.initial_hz.tolist(),
                           "measured_hz": res.measured_hz.tolist(), "updated_hz": res.updated_hz.tolist(),
                           "condition": res.condition,
                           "paper_initial_hz": list(rig.modal_test.paper_initial_hz),
                           "paper_updated_hz": list(rig.modal_test.paper_updated_hz)}
    return out


def _print_report(r: dict) -> None:
    print(f"rig {r['rig']}: rotor mass {r['mass_kg']:.3f} kg; static bearing loads "
          + ", ".join(f"node {k}: {v:.2f} N" for k, v in r["static_loads_N"].items()))
    print("free-free bending frequencies [Hz]: " + ", ".join(f"{f:.2f}" for f in r["free_free_hz"]))
    print("\nnatural frequencies on the bearings [Hz] (damped; F forward, B backward whirl; log dec):")
    for row in r["speeds"]:
        modes = "  ".join(f"{f:7.2f}{w[0].upper()}({d:+.2f})" for f, w, d in
                          zip(row["modes_hz"], row["whirl"], row["log_dec"]))
        print(f"  {row['speed_rpm']:7.0f} rpm  {modes}")
    crit = r["critical_speeds_rpm"]
    print("\ncritical speeds (forward whirl = 1X) [rpm] (damping ratio; > 0.2 is critically damped, API 684): "
          + (", ".join(f"{c:.0f} ({z:.2f})" for c, z in zip(crit, r["critical_damping_ratio"])) or "none in range"))
    thr = r["stability_threshold_rpm"]
    print("stability threshold (onset of oil whip) [rpm]: " + (f"{thr:.0f}" if thr is not None else
                                                               "none in range"))
    print("\nbearing coefficients vs speed (K [N/m], C [N s/m], order " + " ".join(COEFF_ORDER) + "):")
    hdr = f"{'rpm':>7} {'node':>4} " + " ".join(f"{'K' + c:>11}" for c in COEFF_ORDER) + " " + \
        " ".join(f"{'C' + c:>10}" for c in COEFF_ORDER)
    print(hdr)
    for row in r["speeds"]:
        for node, kc in row["bearings"].items():
            K = np.asarray(kc["K"]).ravel()
            C = np.asarray(kc["C"]).ravel()
            print(f"{row['speed_rpm']:7.0f} {node:>4} " + " ".join(f"{v:11.4g}" for v in K) + " "
                  + " ".join(f"{v:10.4g}" for v in C))
    if "updating" in r:
        u = r["updating"]
        print("\nmodel updating against the measured free-free frequencies (paper Table 2 layout):")
        print(u["table"])
        if u["paper_initial_hz"]:
            print("paper's own initial / updated model [Hz]: "
                  + ", ".join(f"{a:.2f}" for a in u["paper_initial_hz"]) + " / "
                  + ", ".join(f"{a:.2f}" for a in u["paper_updated_hz"])
                  + "  (Table 1 geometry gives the 'initial' column above: the paper's rig differs from its table)")


def _plots(r: dict, out: Path) -> list[Path]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cb = r["campbell"]
    rpm = np.array(cb["speeds_rpm"])
    F = np.array(cb["frequency_hz"], dtype=float)
    W = np.array(cb["whirl"], dtype=object)
    fig, ax = plt.subplots(figsize=(7, 5))
    for k in range(F.shape[1]):
        fw = W[:, k] == "forward"
        ax.plot(rpm[fw], F[fw, k], "o", ms=3, color="C0", label="forward" if k == 0 else None)
        ax.plot(rpm[~fw], F[~fw, k], "s", ms=3, color="C3", label="backward" if k == 0 else None)
    ax.plot(rpm, rpm / 60, "k--", lw=1, label="1X")
    for c in r["critical_speeds_rpm"]:
        ax.axvline(c, color="0.6", lw=0.8)
    if r["stability_threshold_rpm"] is not None:
        ax.axvline(r["stability_threshold_rpm"], color="C1", lw=1.5, label="stability threshold")
    ax.set_xlabel("rotor speed [rpm]")
    ax.set_ylabel("damped natural frequency [Hz]")
    ax.set_title(f"Campbell diagram — {r['rig']}")
    ax.set_ylim(0, max(np.nanmax(F) * 1.05, rpm[-1] / 60 * 1.1))
    ax.legend(loc="upper left")
    fig.tight_layout()
    p1 = out / "campbell.png"
    fig.savefig(p1, dpi=110)
    plt.close(fig)

    fig, axs = plt.subplots(1, 2, figsize=(11, 4.5))
    rows = r["speeds"]
    srpm = [row["speed_rpm"] for row in rows]
    for node in rows[0]["bearings"]:
        K = np.array([np.ravel(row["bearings"][node]["K"]) for row in rows])
        C = np.array([np.ravel(row["bearings"][node]["C"]) for row in rows])
        for j, c in enumerate(COEFF_ORDER):
            ls = "-" if node == list(rows[0]["bearings"])[0] else "--"
            axs[0].plot(srpm, K[:, j], ls, color=f"C{j}", marker="o", ms=3, label=f"K{c} node {node}")
            axs[1].plot(srpm, C[:, j], ls, color=f"C{j}", marker="o", ms=3, label=f"C{c} node {node}")
    axs[0].set_ylabel("stiffness [N/m]")
    axs[1].set_ylabel("damping [N s/m]")
    for a in axs:
        a.set_xlabel("rotor speed [rpm]")
        a.grid(alpha=0.3)
        a.legend(fontsize=7, ncol=2)
    fig.suptitle("bearing coefficients vs speed (theory, nominal params)")
    fig.tight_layout()
    p2 = out / "coefficients.png"
    fig.savefig(p2, dpi=110)
    plt.close(fig)
    return [p1, p2]


def run(args) -> int:
    rig = load_rig(args.params)
    if args.max_rpm <= 0:
        raise ParamError("--max-rpm must be > 0")
    if args.modes < 1:
        raise ParamError("--modes must be >= 1")
    r = analyse(rig, _speeds(args, rig), max_rpm=args.max_rpm, n_modes=args.modes, update=not args.no_update)
    _print_report(r)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    paths = _plots(r, out)
    (out / "model.json").write_text(json.dumps(r, indent=1, default=float) + "\n")
    print("\nwrote " + ", ".join(str(p) for p in paths + [out / "model.json"]))
    return 0
