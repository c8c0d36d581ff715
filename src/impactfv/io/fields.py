"""The point fields of the output frames: their names, and the Cauchy stress tensor of every
node from its deformation gradient (any dimension).

Every method writes the fields it has (the FE baselines have no contact status); the case's
``[output] fields`` chooses among them (docs/case-file.md, "Outputs").
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .. import materials as M
from ..backends.cpu import load_matrix, local_matrix, point

#: name -> what it is (docs/case-file.md lists the same)
FIELDS = {
    "velocity": "velocity, m/s (3 components)",
    "displacement": "x - X, m (3 components; reference points + displacement = deformed)",
    "pressure": "-tr(sigma)/3, Pa (compression positive)",
    "von_mises": "von Mises stress, Pa",
    "stress": "Cauchy stress, Pa (6 components xx, yy, zz, xy, yz, xz)",
    "J": "det F",
    "body": "index of the body in the case (integer)",
    "contact_status": "0 open, 1 stick, 2 slip (integer; FV, cases with contact)",
    "contact_pressure": "normal contact traction, Pa (compression positive; FV, cases with "
                        "contact)",
}

#: fields written as integers
INTEGER_FIELDS = ("body", "contact_status")

_cauchy_stress = point(M.cauchy_stress)


@njit(cache=True, parallel=True)
def _stress_kernel(F, node_material, table, out, dim):
    d = len(dim)
    for a in prange(F.shape[0]):
        Fa = local_matrix(d)
        sa = local_matrix(d)
        load_matrix(F, a, Fa)
        szz = _cauchy_stress(Fa, table[node_material[a]], sa)
        for i in range(3):
            for j in range(3):
                out[a, i, j] = 0.0
        for i in range(d):
            for j in range(d):
                out[a, i, j] = sa[i, j]
        if d == 2:
            out[a, 2, 2] = szz


def nodal_stress(F, node_material, table) -> np.ndarray:
    """The 3 x 3 Cauchy stress (n, 3, 3) at every node of deformation gradient F (n, d, d);
    in plane strain (d = 2) with the out-of-plane normal stress sigma_zz."""
    from ..backends.cpu import dim_tag

    out = np.zeros((len(F), 3, 3))
    _stress_kernel(np.ascontiguousarray(F), node_material, table, out, dim_tag(F.shape[1]))
    return out


def vtk_tensor(stress: np.ndarray) -> np.ndarray:
    """(n, 6) components xx, yy, zz, xy, yz, xz of symmetric (n, 3, 3) tensors: the order in
    which ParaView reads a 6-component array as a symmetric tensor."""
    s = np.asarray(stress)
    return np.column_stack([s[:, 0, 0], s[:, 1, 1], s[:, 2, 2], s[:, 0, 1], s[:, 1, 2],
                            s[:, 0, 2]])
