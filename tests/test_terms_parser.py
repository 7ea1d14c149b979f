"""The term parser reads natural algebra and refuses what it cannot read."""

import pytest

from jointid.errors import IdentificationError
from jointid.identify.terms import library


@pytest.mark.parametrize(
    "spec",
    ["q + -q^3 + q'", "q - q^3 + q'", "q+-q^3+q'", "q, -q^3, q'", "eq21", "EQ21", "seed", "q - q**3 + v",
     ["q", "-q^3", "q'"]],
)
def test_spellings_of_the_seed_model(spec):
    lib = library(spec)
    assert lib.names == ("q", "-q^3", "q'")
    assert lib.coefficient_names == ("omega1^2", "k3", "c")


def test_eq22_and_products():
    assert library("eq22").names == ("q", "-q^3", "q'", "|q'|q'", "q'^3")
    assert library("q - q^3 + q^2 q' + sign(q')").names == ("q", "-q^3", "q^2 q'", "sign(q')")
    assert library("q - q^3 + q^2*q'").names == ("q", "-q^3", "q^2 q'")


@pytest.mark.parametrize(
    "spec, hint",
    [("q - q3 + q'", "'-q^3'"), ("q + q'3", "\"q'^3\""), ("q + + q'", "not followed by a term"),
     ("q - - q^3", "not followed by a term"), ("q -", "not followed by a term"), ("q, , q'", "empty term"),
     ("", "empty"), ("q + q^4", "unknown term 'q^4'"), ("q + cos(q)", "unknown term")],
)
def test_refused_with_a_hint(spec, hint):
    with pytest.raises(IdentificationError, match="term") as info:
        library(spec)
    assert hint in str(info.value)
