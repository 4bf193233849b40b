"""
`bearing-id design`: the experiment-design check from the command line.

Rank 8 of 16 for unbalance at one midspan station -- the independent trial's finding -- and a determined force plan.
"""
from bearing_id.cli import main


def test_unbalance_at_midspan_is_rank_8_and_refused(capsys):
    assert main(['design', '--speeds', '1500']) == 1
    out = capsys.readouterr().out
    assert 'rank 8 of 16 (numerical' in out and 'advice: add' in out and 'does NOT determine' in out


def test_force_plan_is_determined(capsys):
    assert main(['design', '--speeds', '1500', '--scenario', 'force']) == 0
    assert 'rank 16 of 16 (numerical' in capsys.readouterr().out


def test_bad_input_is_a_parameter_error(capsys):
    assert main(['design', '--speeds', '0']) == 2
    assert main(['design', '--probes', '6z']) == 2
