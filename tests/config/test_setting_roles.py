"""Each setting declares its role and its range once (`config.roles`): every setting has
exactly one role, a number its range, and a setting declared without them is refused."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, fields, replace

import pytest

from seqrank.config import Role, TrainConfig, settings_of, validate
from seqrank.config.ranges import Count, Number
from seqrank.config.roles import ROLE, accepted_by, check_declared, declare, role_of
from seqrank.errors import SettingError
from seqrank.reference import REFERENCE_FILE, REFERENCE_KEY


def test_every_setting_has_exactly_one_role():
    for setting in fields(TrainConfig):
        assert isinstance(setting.metadata[ROLE], Role), setting.name
    by_role = [settings_of(role) for role in Role]
    assert sum(len(names) for names in by_role) == len(fields(TrainConfig))  # none twice
    assert set().union(*by_role) == {f.name for f in fields(TrainConfig)}  # none left out
    assert all(by_role), "a role no setting has"


def test_every_number_has_its_range_and_nothing_else_has_one():
    for setting in fields(TrainConfig):
        accepted = accepted_by(setting)
        if setting.type == "int":
            assert isinstance(accepted, Count), setting.name
        elif setting.type == "float":
            assert isinstance(accepted, Number), setting.name
        else:
            assert accepted is None, setting.name


def test_a_setting_without_a_role_is_refused_by_name():
    @dataclass(frozen=True)
    class Unclassified:
        hidden: int = declare(Role.AGENT, 1024, Count())
        dropout: float = 0.1

    with pytest.raises(TypeError, match="dropout has no role"):
        check_declared(Unclassified)


def test_a_number_without_its_range_and_a_range_on_a_text_are_refused():
    @dataclass(frozen=True)
    class Unranged:
        dropout: float = declare(Role.AGENT, 0.1)
        layers: int = declare(Role.AGENT, 2, Number())
        name: str = declare(Role.RUN, "x", Count())
        also: int = field(default=0, metadata={ROLE: "agent"})  # a text, not a Role

    with pytest.raises(TypeError) as refused:
        check_declared(Unranged)
    for problem in (
        "dropout (float) needs a Number range",
        "layers (int) needs a Count range",
        "name (str) has a range but is no number",
        "also has no role",
    ):
        assert problem in str(refused.value)


def test_role_of_reads_the_declared_role():
    [seed] = [f for f in fields(TrainConfig) if f.name == "seed"]
    assert role_of(seed) is Role.RUN and accepted_by(seed) == Count(low=0, high=2**32 - 1)


def _outside(accepted):
    """Values just outside a range, and of the wrong kind."""
    if isinstance(accepted, Count):
        return [accepted.low - 1, accepted.high + 1, 1.5, True]
    return [
        -0.5,
        *([] if accepted.from_zero else [0.0]),
        *([1.5] if accepted.at_most_one else []),
        math.nan,
        math.inf,
        "1",
    ]


NUMBERS = [f for f in fields(TrainConfig) if accepted_by(f) is not None]


@pytest.mark.parametrize("setting", NUMBERS, ids=[f.name for f in NUMBERS])
def test_validate_refuses_each_number_outside_its_declared_range(setting):
    config = TrainConfig()
    for value in _outside(accepted_by(setting)):
        with pytest.raises(SettingError, match=f"^{setting.name} must be"):
            validate(replace(config, **{setting.name: value}))


def test_the_shipped_reference_is_keyed_by_the_reference_key():
    """A new setting that joins the key (an agent setting) leaves the shipped entries
    behind: measure them again, or name the setting in `reference.SAME_LEARNING`."""
    for entry in json.loads(REFERENCE_FILE.read_text())["entries"]:
        assert list(entry["settings"]) == list(REFERENCE_KEY)
