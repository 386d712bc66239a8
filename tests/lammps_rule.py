"""demkit's own friction code with LAMMPS' sliding rule swapped in, for tests/test_lammps.py.

demkit and LAMMPS' ``tangential linear_history`` differ on purpose in one line: when a contact
slides, demkit stores xi = -F_t/k_t (the spring holds the whole Coulomb force), LAMMPS
xi = -(F_t + eta_t v_t)/k_t (pair_granular.cpp, 29 Sep 2021, lines 518-523). To show that this
line is the *only* difference, :func:`lammps_rule_contact` reads the engine's current
``demkit/interactions/friction.py`` and ``contact.py``, replaces the three sliding assignments
``s? = -f? / kt`` by ``s? = -(f? + eta * t?) / kt`` and loads the result as a separate module.
Everything else (slip velocity, history rotation, Coulomb limit, torques, kernels) is the engine's
own code, so the cross-check follows the engine as it changes.

The module names carry a hash of the altered sources, so that demkit's kernel cache (keyed on the
generated source, which imports these modules by name) can never mix two versions.
"""
from __future__ import annotations

import hashlib
import importlib.util
import re
import sys
from pathlib import Path

import demkit.interactions.contact as contact
import demkit.interactions.friction as friction

#: the sliding assignments of demkit's tangential_force (one per component)
SLIDING = re.compile(r"^(?P<pad>[ \t]*)s(?P<c>[xyz]) = -f(?P=c) / kt\b.*$", re.M)
PACKAGE = "demkit.interactions"


def lammps_rule_sources():
    """(friction source, contact source) with LAMMPS' sliding rule; RuntimeError if the engine's
    sliding lines are no longer where this expects them."""
    text = Path(friction.__file__).read_text()
    altered, count = SLIDING.subn(
        lambda m: f"{m['pad']}s{m['c']} = -(f{m['c']} + eta * t{m['c']}) / kt  # LAMMPS' sliding rule", text)
    if count != 3:
        raise RuntimeError(f"expected the 3 sliding assignments 's? = -f? / kt' in {friction.__file__}, found "
                           f"{count}: update tests/lammps_rule.py to the engine's friction code")
    contact_text = Path(contact.__file__).read_text()
    if contact_text.count("from .friction import") != 1:
        raise RuntimeError(f"expected one 'from .friction import' in {contact.__file__}")
    return altered, contact_text


def lammps_rule_contact(folder):
    """Module with ``Friction`` and ``KelvinVoigt`` whose friction keeps LAMMPS' sliding spring.

    The altered sources are written into ``folder`` (numba's cache needs files) and registered in
    sys.modules under hashed names inside demkit.interactions (their relative imports resolve there).
    """
    fric_text, contact_text = lammps_rule_sources()
    tag = hashlib.sha256((fric_text + contact_text).encode()).hexdigest()[:12]
    fric_name = f"_lammps_rule_friction_{tag}"
    contact_name = f"_lammps_rule_contact_{tag}"
    contact_text = contact_text.replace("from .friction import", f"from .{fric_name} import")
    if f"{PACKAGE}.{contact_name}" in sys.modules:
        return sys.modules[f"{PACKAGE}.{contact_name}"]
    for name, text in ((fric_name, fric_text), (contact_name, contact_text)):
        path = Path(folder) / f"{name}.py"
        path.write_text(text)
        spec = importlib.util.spec_from_file_location(f"{PACKAGE}.{name}", path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module
        spec.loader.exec_module(module)
    return sys.modules[f"{PACKAGE}.{contact_name}"]
