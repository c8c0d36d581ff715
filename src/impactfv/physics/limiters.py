"""Slope limiters of the linear reconstruction, as point functions (docs/theory.md,
"Reconstruction and limiter").

For a node a and one component u: d = grad(u)_a . (X_mid - X_a) is the change the
reconstruction makes at an edge midpoint, and dmax the room to the largest (d > 0) or
smallest (d < 0) value among a and its neighbours. Each returns the factor phi <= 1 that
keeps u_a + phi d within that range; the node takes the smallest phi over its edges.
"""

NONE = 0
BARTH_JESPERSEN = 1
VENKATAKRISHNAN = 2
IDS = {"none": NONE, "barth_jespersen": BARTH_JESPERSEN, "venkatakrishnan": VENKATAKRISHNAN}

# The U-MUSCL blend acts where the jump between the two sides' extrapolations is below this
# fraction of the nodal change (docs/theory.md, "U-MUSCL blend").
SMOOTHNESS = 0.1

# The smoothness switch acts where the jump between the two reconstructed states is below this
# fraction of the nodal change (docs/theory.md, "Smoothness switch"): on a smooth field the
# ratio is O(h^2), and modes with fewer than about ten cells per wavelength keep the whole
# upwind dissipation (with 0.1 a bouncing block's vibrations gained energy).
SWITCH_RATIO = 0.01


def barth_jespersen(dmax, d):
    """phi = min(1, dmax / d): the largest factor that creates no new extremum (the TVD
    shock capturing of the seed's abstract). dmax and d have the same sign, so the
    comparison gives the same result as min without a division where no limiting is needed."""
    if abs(d) <= abs(dmax):
        return 1.0
    return dmax / d


def venkatakrishnan(dmax, d, eps2):
    """A smooth version of Barth-Jespersen (TVD shock capturing, seed abstract) that leaves
    smooth extrema almost untouched; eps2 sets the size below which changes are not limited."""
    num = (dmax * dmax + eps2) * d + 2.0 * d * d * dmax
    den = dmax * dmax + 2.0 * d * d + d * dmax + eps2
    return num / (den * d)


def limiter_factor(kind, u, umin, umax, d):
    """phi for a reconstruction change d of a value u with neighbour range [umin, umax]."""
    dmax = umax - u if d > 0.0 else umin - u
    if kind == BARTH_JESPERSEN:
        return barth_jespersen(dmax, d)
    # eps^2 = 0.027 (umax - umin)^2, i.e. K = 0.3 relative to the local range
    return venkatakrishnan(dmax, d, 0.027 * (umax - umin) * (umax - umin))


def blend_weight(chi, change, r_a, r_b):
    """The U-MUSCL weight of one field on an edge ab (docs/theory.md, "U-MUSCL blend"):
    chi where the field is smooth, falling linearly to 0 where the two sides' linear
    extrapolations to the midpoint part by SMOOTHNESS times the nodal change or more.
    change = u_b - u_a; r_a, r_b: grad u_a . (X_mid - X_a) and grad u_b . (X_mid - X_a)
    (limited). On a smooth field the jump change - r_a - r_b between the two extrapolations
    is O(h^3) against a change of O(h); across a grid-scale (sawtooth) mode the gradients
    vanish and the jump is the whole change, which keeps the full upwind damping there."""
    jump = abs(change - r_a - r_b)
    limit = SMOOTHNESS * abs(change)
    if jump >= limit:
        return 0.0
    return chi * (1.0 - jump / limit)


def switch_factor(chi, jump2, change2):
    """The factor 1 - chi S of an upwind term on an edge (docs/theory.md, "Smoothness
    switch"): S = 1 - |jump|^2 / (SWITCH_RATIO |change|)^2 where the jump between the two
    sides' reconstructed states is below SWITCH_RATIO times the change between the nodal
    values, 0 elsewhere (``jump2``, ``change2``: the squared norms, of the velocity vector
    for the momentum flux's Z [[v]] / 2 and of the Cauchy stress for the geometric flux's
    [[t]] / (2 rho c_p)). So 1 - chi on a well resolved smooth field, 1 at fronts and on
    grid-scale modes, where the limiter or the gradients leave the jump about as large as
    the change. It only ever removes part of a dissipation: the central parts are left as
    they are."""
    # without a branch: a change of 0 with a jump gives a huge ratio and S = 0 (with neither
    # the term is zero anyway)
    smooth = max(0.0, 1.0 - jump2 / (SWITCH_RATIO * SWITCH_RATIO * change2 + 1e-300))
    return 1.0 - chi * smooth


def switch_scales(chi, v, sigma, a, b, dv, Sa, Sb, geometric):
    """The smoothness switch's factors (momentum, geometric) on edge ab (docs/theory.md,
    "Smoothness switch"): switch_factor of the reconstructed velocity jump dv against
    v_b - v_a for the momentum flux's Z [[v]] / 2, and (``geometric``: the upwind geometric
    flux; 1 otherwise) of the reconstructed stresses' jump Sb - Sa against
    sigma_b - sigma_a, in the Frobenius norm, for its [[t]] / (2 rho c_p)."""
    d = dv.shape[0]
    jump2 = 0.0
    change2 = 0.0
    for i in range(d):
        change = v[b, i] - v[a, i]
        jump2 += dv[i] * dv[i]
        change2 += change * change
    momentum = switch_factor(chi, jump2, change2)
    if not geometric:
        return momentum, 1.0
    jump2 = 0.0
    change2 = 0.0
    for i in range(d):
        for j in range(d):
            jump = Sb[i, j] - Sa[i, j]
            change = sigma[b, i, j] - sigma[a, i, j]
            jump2 += jump * jump
            change2 += change * change
    return momentum, switch_factor(chi, jump2, change2)
