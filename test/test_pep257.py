"""
Docstring style: ament_pep257 on the package, as ``colcon test`` runs it (ament's convention).

colcon runs the tests from the package root (the repository root); pydocstyle skips directories whose names start
with '.' or '_' (``.venv``, ``__pycache__``) by itself.  Build output that can appear in the package root is not our
source and is excluded.
"""
from pathlib import Path

from ament_pep257.main import main
import pytest

ROOT = Path(__file__).resolve().parent.parent
EXCLUDE = ['build', 'install', 'log', 'out', 'msg_defs/build']


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257(monkeypatch):
    monkeypatch.chdir(ROOT)
    rc = main(argv=['.', 'test', '--exclude', *EXCLUDE])
    assert rc == 0, 'Found code style errors / warnings (see the output above)'
