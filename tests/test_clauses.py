"""Every clause of the visibility rule is needed: with the clause turned
off (baker/solve/visibility.py: VOXGI_DISABLE_CLAUSE, honoured only when
the kernels run as Python, NUMBA_DISABLE_JIT=1, so no compiled kernel ever
lacks one), some test of tests/test_visibility_rule.py fails. A clause no
test misses would be untested, or dead."""
import os
import subprocess
import sys

import pytest

from baker.solve.visibility import CLAUSES

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def rule_tests(clause=""):
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1", "VOXGI_DISABLE_CLAUSE": clause}
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           os.path.join(ROOT, "tests", "test_visibility_rule.py")], capture_output=True, text=True,
                          cwd=ROOT, env=env, timeout=600)


def test_the_rule_tests_pass_as_python():
    """The reference for the runs below: the kernels as Python pass them."""
    r = rule_tests()
    assert r.returncode == 0, r.stdout[-3000:]


@pytest.mark.parametrize("clause", CLAUSES)
def test_each_clause_is_missed_by_some_rule_test(clause):
    r = rule_tests(clause)
    assert r.returncode == 1 and " failed" in r.stdout, (clause, r.stdout[-2000:])


def test_an_unknown_clause_is_refused():
    r = rule_tests("no_such_clause")
    assert r.returncode != 0 and "not a clause" in r.stdout + r.stderr
