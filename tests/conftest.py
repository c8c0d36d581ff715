import copy
import subprocess
import sys

import pytest

COPPER = {"name": "copper", "model": "neo_hookean", "density": 8930.0,
          "youngs_modulus": 585.0e6, "poisson_ratio": 0.495}


def block_case(divisions=(20, 8), size=(0.01, 0.004), velocity=(0.0, 0.0), end_time=2e-6,
               boundary=(), material=None, pattern="alternate", **run):
    """A one-body rectangle case as a dict."""
    return {
        "run": {"end_time": end_time, **run},
        "material": [dict(material or COPPER)],
        "body": [{"name": "block", "material": (material or COPPER)["name"],
                  "velocity": velocity,
                  "mesh": {"generator": "rectangle", "origin": [0.0, 0.0], "size": list(size),
                           "divisions": list(divisions), "pattern": pattern},
                  "boundary": [dict(b) for b in boundary]}],
    }


@pytest.fixture
def block():
    return lambda **kw: copy.deepcopy(block_case(**kw))


def run_cli(*args, **kwargs):
    """Run ``python -m impactfv.cli ARGS`` and capture its output."""
    return subprocess.run([sys.executable, "-m", "impactfv.cli", *map(str, args)],
                          capture_output=True, text=True, **kwargs)
