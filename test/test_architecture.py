"""
The import contracts of pyproject.toml ([tool.importlinter]), checked by import-linter's ``lint-imports``.

Layers (a module imports only from its own layer or below), physics without ROS, bag libraries or plotting, and no
import cycles between the modules of any package; docs/ARCHITECTURE.md lists them.  import-linter's graph includes
imports made inside functions.
"""
from pathlib import Path
import shutil
import subprocess
import sys

ROOT = Path(__file__).resolve().parent.parent


def lint_imports() -> str:
    """Return the lint-imports script beside this Python (a venv), else the one on PATH (colcon test)."""
    beside = Path(sys.executable).with_name('lint-imports')
    return str(beside) if beside.exists() else (shutil.which('lint-imports') or str(beside))


def test_import_contracts_are_kept():
    exe = lint_imports()
    r = subprocess.run([str(exe), '--no-cache'], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]
    assert 'BROKEN' not in r.stdout and '3 kept, 0 broken' in r.stdout, r.stdout[-2000:]


def test_a_broken_contract_is_reported(tmp_path):
    """The check can fail: a physics module that imports the CLI breaks the layers contract."""
    shutil.copytree(ROOT / 'bearing_id', tmp_path / 'bearing_id', ignore=shutil.ignore_patterns('__pycache__'))
    shutil.copy(ROOT / 'pyproject.toml', tmp_path / 'pyproject.toml')
    conv = tmp_path / 'bearing_id' / 'rotor' / 'elements.py'
    conv.write_text(conv.read_text() + '\nfrom ..commands import identify as _upward  # noqa\n')
    exe = lint_imports()
    r = subprocess.run([str(exe), '--no-cache'], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                       env={'PATH': '/usr/bin:/bin', 'PYTHONPATH': str(tmp_path)})
    assert r.returncode != 0 and 'bearing_id.rotor.elements -> bearing_id.commands.identify' in r.stdout, r.stdout
