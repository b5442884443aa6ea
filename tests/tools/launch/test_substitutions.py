"""``$(...)`` substitutions: var, env, optenv, dirname, nesting, quoting, and their errors."""
from __future__ import annotations

import pytest

from dptpu.tools.launch.substitutions import SubstitutionContext, SubstitutionError, substitute


def _context(**variables):
    return SubstitutionContext(variables=variables, launch_file_dir="/launch/dir",
                               environ={"HOME_DIR": "/home/me", "EMPTY": "", "WHICH": "HOME_DIR"})


def test_text_around_substitutions_is_kept():
    assert substitute("/$(var ns)/camera_$(var n)", _context(ns="rig", n="2")) == "/rig/camera_2"
    assert substitute("no substitution (here)", _context()) == "no substitution (here)"


def test_env_with_and_without_default_and_optenv():
    context = _context()
    assert substitute("$(env HOME_DIR)", context) == "/home/me"
    assert substitute("$(env EMPTY fallback)", context) == ""  # set but empty is still set
    assert substitute("$(env MISSING 'two words')", context) == "two words"
    assert substitute("$(optenv MISSING)", context) == ""
    assert substitute("$(optenv MISSING 7)", context) == "7"
    with pytest.raises(SubstitutionError, match=r"environment variable 'MISSING' is not set and \$\(env MISSING\) "
                                                r"has no default"):
        substitute("$(env MISSING)", context)


def test_nested_substitutions_and_dirname():
    assert substitute("$(env $(var which))", _context(which="HOME_DIR")) == "/home/me"
    assert substitute("$(dirname)/params.yaml", _context()) == "/launch/dir/params.yaml"


@pytest.mark.parametrize(("text", "message"), [
    ("$(var)", r"\$\(var\) takes 1 argument, got 0"),
    ("$(var a b)", r"\$\(var\) takes 1 argument, got 2"),
    ("$(vra x)", r"unknown substitution '\$\(vra \.\.\.\)' \(did you mean 'var'\?\)"),
    ("$(var x", r"unterminated substitution '\$\(var' .*missing '\)'"),
    ("$(env 'x)", r"unterminated quote '"),
    ("$()", r"a substitution needs a name"),
    ("$(var nope)", r"undeclared launch argument 'nope' in \$\(var nope\); .*\(declared: rate\)"),
])
def test_malformed_substitutions_raise_with_a_reason(text, message):
    with pytest.raises(SubstitutionError, match=message):
        substitute(text, _context(rate="10"))
