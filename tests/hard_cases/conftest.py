"""Hard cases (issue 10): scenes at the edge of what the engine handles. Each either runs with no
NaN and a bounded energy error (the bound quoted and explained in its test) or stops before
stepping with a message that says what to change. docs/stability.md lists what each one shows.
Every test here is marked ``hard_case``: ``pytest -m hard_case tests`` runs them alone."""
import re

import pytest


def advice(message, name):
    """The value of 'Use <name> <= x' (or '>= x') in a guard's message."""
    found = re.search(rf"Use {name} [<>]= ([0-9][0-9.e+-]*[0-9])", message)
    assert found, message
    return float(found.group(1))


def refused(make):
    """The message of the ValueError raised by ``make()``."""
    with pytest.raises(ValueError) as info:
        make()
    return str(info.value)


def balance(traj):
    """max |total + dissipated - initial| over the run."""
    budget = traj.energy["total"] + traj.energy["dissipated"]
    return float(abs(budget - budget[0]).max())
