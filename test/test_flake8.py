"""
Code style: ament_flake8 on the package, as ``colcon test`` runs it (ament's configuration, lines up to 120).

colcon runs the tests from the package root (the repository root) and ament_flake8 checks every ``.py`` below it;
it skips directories whose names start with '.' or '_' (``.venv``, ``__pycache__``) by itself.  Build output that
can appear in the package root is not our source and is excluded.
"""
from pathlib import Path

from ament_flake8.main import main_with_errors
import pytest

ROOT = Path(__file__).resolve().parent.parent
EXCLUDE = ['build', 'install', 'log', 'out']


@pytest.mark.flake8
@pytest.mark.linter
@pytest.mark.slow(reason='flake8 with its plugins over every file of the repository (~8-14 s)')
def test_flake8(monkeypatch):
    monkeypatch.chdir(ROOT)
    rc, errors = main_with_errors(argv=['--linelength', '120', '--exclude', *EXCLUDE])
    assert rc == 0, f'Found {len(errors)} code style errors / warnings:\n' + '\n'.join(errors)
