"""Shared test fixtures: one definition per material and the small cases built on them."""

import copy
import os
import subprocess
import sys

# one numba thread unless a test is about threads: waiting threads spin at every barrier,
# and on a busy machine a parallel kernel on a small mesh then takes milliseconds
os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
import pytest

from impactfv.physics.materials import Material
from impactfv.validation.bars import SEED_MATERIAL
from impactfv.validation.standing_wave import RUBBER

#: the seed paper's nearly incompressible neo-Hookean copper (nu = 0.495)
COPPER = SEED_MATERIAL
#: the same copper at nu = 0.3 (a compressible neo-Hookean solid)
COPPER_03 = dict(SEED_MATERIAL, name="copper03", poisson_ratio=0.3)
#: linear elastic rubber of the standing-wave validation
RUBBER = RUBBER
#: a soft compressible solid
SOFT = {"name": "soft", "model": "neo_hookean", "density": 1000.0, "youngs_modulus": 1.0e6,
        "poisson_ratio": 0.3}


def material_toml(entry=None) -> str:
    """The ``[[material]]`` table of a material entry (seed copper by default), as TOML."""
    entry = entry or COPPER
    return "[[material]]\n" + "".join(f"{k} = {v!r}\n" for k, v in entry.items()).replace("'", '"')


def material(entry) -> Material:
    return Material.from_entry(entry)


def block_case(divisions=(20, 8), size=(0.01, 0.004), velocity=(0.0, 0.0), end_time=2e-6,
               boundary=(), material=None, pattern="alternate", **run):
    """A one-body rectangle case as a dict (seed copper unless ``material`` is given)."""
    material = material or COPPER
    return {
        "run": {"end_time": end_time, **run},
        "material": [dict(material)],
        "body": [{"name": "block", "material": material["name"],
                  "velocity": velocity,
                  "mesh": {"generator": "rectangle", "origin": [0.0, 0.0], "size": list(size),
                           "divisions": list(divisions), "pattern": pattern},
                  "boundary": [dict(b) for b in boundary]}],
    }


def box_case(divisions=(8, 4, 4), size=(0.004, 0.002, 0.002), velocity=(0.0, 0.0, 0.0),
             end_time=2e-6, boundary=(), material=None, **run):
    """A one-body box of tetrahedra as a dict (seed copper unless ``material`` is given)."""
    material = material or COPPER
    return {
        "run": {"end_time": end_time, **run},
        "material": [dict(material)],
        "body": [{"name": "block", "material": material["name"], "velocity": list(velocity),
                  "mesh": {"generator": "box", "origin": [0.0, 0.0, 0.0], "size": list(size),
                           "divisions": list(divisions)},
                  "boundary": [dict(b) for b in boundary]}],
    }


@pytest.fixture
def block():
    return lambda **kw: copy.deepcopy(block_case(**kw))


def run_cli(*args, **kwargs):
    """Run ``python -m impactfv.cli ARGS`` and capture its output."""
    return subprocess.run([sys.executable, "-m", "impactfv.cli", *map(str, args)],
                          capture_output=True, text=True, **kwargs)


def deformation(F3):
    """The d x d array of a deformation gradient given as nested lists."""
    return np.array(F3, float)
