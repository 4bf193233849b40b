"""
The console scripts start numpy with one BLAS thread unless the user chose a thread count (bearing_id.blas_threads).

Why it matters (bearing_id/blas_threads.py): with OpenBLAS's default pool ``bearing-id identify
--method direct`` of the 9-speed benchmark files took 4.4-4.8 s CPU on this project's 2-core machine, 2.3-2.4 s with
one thread.
"""
import os
import subprocess
import sys

from bearing_id import blas_threads
import pytest


def _clean_env(**extra):
    env = {k: v for k, v in os.environ.items() if k not in blas_threads.THREAD_VARS}
    env.update(extra)
    return env


@pytest.mark.parametrize('module', ['bearing_id.cli', 'bearing_id.nodes.kf_estimator'])
def test_entry_points_set_one_thread_before_numpy(module):
    """The entry module sets OPENBLAS_NUM_THREADS=1 before numpy loads (a fresh interpreter, nothing set)."""
    code = ('import sys\nimport {module}\n'
            "import os\nprint(os.environ.get('OPENBLAS_NUM_THREADS'))").format(module=module)
    # numpy must not be imported before the setting: check by importing the setter first in a clean process that
    # records whether numpy was loaded at the moment blas_threads ran
    check = ('import sys, builtins\nseen = {}\nreal = builtins.__import__\n'
             'def imp(name, *a, **k):\n'
             "    if name.endswith('blas_threads') or (len(a) > 2 and a[2] and 'blas_threads' in a[2]):\n"
             "        seen.setdefault('numpy_before', 'numpy' in sys.modules)\n"
             '    return real(name, *a, **k)\n'
             'builtins.__import__ = imp\n' + code + "\nprint(seen.get('numpy_before'))")
    out = subprocess.run([sys.executable, '-c', check], capture_output=True, text=True, env=_clean_env(),
                         timeout=120)
    assert out.returncode == 0, out.stderr
    value, numpy_before = out.stdout.split()[-2:]
    assert value == '1'
    assert numpy_before == 'False'


def test_a_user_setting_wins():
    """Any thread variable the user set is left alone (OMP_NUM_THREADS=3: OPENBLAS_NUM_THREADS stays unset)."""
    env = {'OMP_NUM_THREADS': '3'}
    assert blas_threads.limit_to_one(env) is False
    assert env == {'OMP_NUM_THREADS': '3'}
    env = {'OPENBLAS_NUM_THREADS': '2'}
    assert blas_threads.limit_to_one(env) is False
    assert env['OPENBLAS_NUM_THREADS'] == '2'
    env = {}
    assert blas_threads.limit_to_one(env) is True
    assert env['OPENBLAS_NUM_THREADS'] == '1'
