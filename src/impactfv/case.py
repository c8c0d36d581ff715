"""The case file: a strict schema (an unknown key is an error) and ``load_case``.

A case is a TOML file or a dict of the same structure. Validation happens here, once; the
run pipeline receives a validated :class:`Case` with every body's mesh already read and checked.
"""

from __future__ import annotations

import difflib
import math
import tomllib
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal, Optional, Union, get_args, get_origin

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from .errors import InputError
from .expr import compile_expression
from .physics.materials import Material
from .mesh.generators import DIAGONAL_PATTERNS, annulus, box, disc, rectangle
from .mesh.reader import read_mesh
from .mesh.core import Mesh, validate_and_orient

#: the point fields of the output frames (docs/case-file.md lists the same)
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

#: fields of the frames written as integers
INTEGER_FIELDS = ("body", "contact_status")


LIMITERS = ("none", "barth_jespersen", "venkatakrishnan")
METHODS = ("fv", "fem-t3", "fem-q4md")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", arbitrary_types_allowed=True)


#: a point or vector of the case: 2 components in 2D, 3 in 3D (the mesh decides, and
#: load_case checks every vector against it)
Vector = Annotated[list[float], Field(min_length=2, max_length=3)]
Counts = Annotated[list[int], Field(min_length=2, max_length=3)]
#: a load component: a number, or an expression of x, y, z (reference position, m) and t (s)
Load = Union[float, str]
LoadVector = Annotated[list[Load], Field(min_length=2, max_length=3)]
#: variables of load expressions, in the order they are passed
LOAD_VARIABLES = ("x", "y", "z", "t")


def _finite_load(value):
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError("must be finite")
    return value


class RunSettings(_Strict):
    end_time: float = Field(ge=1e-15, description="simulated time to reach, s (a smaller "
                            "one is below any stable time step of a solid)")
    cfl: float = Field(0.4, gt=0, le=1, description="Courant number of the time step")
    output_interval: Optional[float] = Field(None, gt=0, description="snapshot cadence, s")
    order: Literal[1, 2] = 2
    limiter: Literal["none", "barth_jespersen", "venkatakrishnan"] = "barth_jespersen"
    method: Literal["fv", "fem-t3", "fem-q4md"] = "fv"
    geometric_flux: Literal["central", "upwind"] = "upwind"
    muscl_chi: float = Field(
        0.0, ge=0, le=1, description="blend of the reconstruction to an edge midpoint "
        "(U-MUSCL) where the field is smooth: 0 extrapolates with the node's limited "
        "gradient, 1 takes the mean of the edge's two nodes, both parts scaled by the node's "
        "limiter factor; grid-scale oscillations always get the gradient's (docs/theory.md, "
        "U-MUSCL blend)")
    smooth_switch: float = Field(
        0.0, ge=0, le=1, description="fraction chi of the upwind dissipation (both the "
        "momentum flux's Z [[v]] / 2 and the geometric flux's [[t]] / (2 rho c_p)) removed "
        "on edges where the reconstructed jump is a small part of the nodal change; fronts, "
        "grid-scale modes and contact keep all of it. 0: off (default); 0.6 takes 40% of the "
        "energy the plain terms take from a smooth wave (docs/theory.md, Smoothness switch)")
    boundary_correction: Optional[Literal["normal", "full"]] = Field(
        None, description="the F equation's velocity on a free or loaded boundary face: the "
        "interior velocity corrected by the characteristic jump along the normal only, or in "
        "every direction; unset: normal in 2D, full in 3D (docs/theory.md, Boundaries)")
    compatibility_time: float = Field(
        30.0, ge=0, description="relaxation time of the grid-scale part of F's mismatch with "
        "the Green-Gauss gradient of the nodal positions, in p-wave transit times h / c_p of "
        "each node's shortest edge; 0: off. Damps the incompatible rotations of F that the "
        "upwind geometric flux makes grow under compression (docs/theory.md, Compatibility "
        "relaxation)")
    angular_momentum: Literal["unprojected", "projected"] = Field(
        "unprojected", description="projected: every free body (no held velocity component) "
        "keeps its angular momentum to round-off, the interior fluxes' torque removed by a "
        "rigid angular acceleration each stage; loads, contact and body forces keep theirs. "
        "Its price: the energy of a spinning body is no longer monotone (docs/theory.md, "
        "Momentum: linear and angular)")
    max_steps: Optional[int] = Field(None, gt=0, description="cap on the number of steps; "
                                     "unset: 10,000,000, and a run estimated to need more is "
                                     "refused before it starts")
    threads: Optional[int] = Field(None, gt=0, description="CPU threads of the kernels; "
                                   "unset: the cores this process may use")
    backend: Literal["cpu", "cuda"] = Field("cpu", description="where the FV kernels run: "
                                            "cpu (numba) or cuda (numba-cuda, an NVIDIA GPU)")

    @field_validator("end_time", "cfl", "output_interval", "muscl_chi", "compatibility_time",
                     "smooth_switch")
    @classmethod
    def _finite(cls, value):
        if value is not None and not math.isfinite(value):
            raise ValueError("must be a finite number")
        return value

    # options of the finite-volume scheme alone: the FE baselines would ignore them
    FV_ONLY: ClassVar[tuple] = ("order", "limiter", "geometric_flux", "muscl_chi",
                                "smooth_switch", "boundary_correction", "compatibility_time",
                                "angular_momentum")

    @model_validator(mode="after")
    def _sensible_interval(self):
        if self.output_interval is not None and self.output_interval < 1e-9 * self.end_time:
            raise ValueError(f"output_interval must be at least 1e-9 x end_time "
                             f"({1e-9 * self.end_time:.3g} s)")
        return self

    @model_validator(mode="after")
    def _no_option_that_would_be_ignored(self):
        # a value other than the default (a dumped default, as `compare` re-loads its case,
        # is not a choice the user made) of an option the chosen method does not have
        if self.method != "fv":
            for key in self.FV_ONLY:
                if getattr(self, key) != type(self).model_fields[key].default:
                    raise ValueError(f"{key} is an option of method = \"fv\"; method = "
                                     f"\"{self.method}\" would ignore it (drop it, or run "
                                     f"`impactfv compare` to run both)")
        elif self.order == 1 and self.muscl_chi != 0.0:
            raise ValueError("muscl_chi blends the order-2 reconstruction; order = 1 has "
                             "none (drop muscl_chi, or set order = 2)")
        elif self.order == 1 and self.smooth_switch:
            raise ValueError("smooth_switch acts on the jumps of the order-2 reconstruction; "
                             "order = 1 has none (drop smooth_switch, or set order = 2)")
        elif self.muscl_chi != 0.0 and self.smooth_switch:
            raise ValueError("muscl_chi and smooth_switch are alternatives: together the "
                             "energy of a smooth wave can rise (docs/theory.md); set one of "
                             "them to 0")
        return self


class MaterialSpec(_Strict):
    name: str = Field(min_length=1)
    model: Literal["neo_hookean", "linear_elastic"] = "neo_hookean"
    density: float = Field(gt=0, allow_inf_nan=False)
    youngs_modulus: float = Field(gt=0, allow_inf_nan=False)
    poisson_ratio: float = Field(gt=-1.0, lt=0.5, allow_inf_nan=False)

    @model_validator(mode="after")
    def _representable(self):
        # E = 1.7e308 is finite, but its Lame constants and wave speed are not (or a tiny
        # density makes c_p overflow): refuse what the time step cannot be computed from
        m = Material(self.name, self.model, self.density, self.youngs_modulus,
                     self.poisson_ratio)
        try:
            speed_and_impedance = (m.p_wave_speed, m.p_impedance)
        except (OverflowError, ZeroDivisionError, ValueError):
            speed_and_impedance = (math.inf,)
        if not all(math.isfinite(v) and v > 0 for v in speed_and_impedance):
            raise ValueError("youngs_modulus, density and poisson_ratio give no finite wave "
                             "speed and impedance (values too extreme for double precision)")
        return self


class MeshSpec(_Strict):
    generator: Optional[Literal["rectangle", "disc", "annulus", "box"]] = None
    origin: Optional[Vector] = None
    size: Optional[Vector] = None
    divisions: Optional[Counts] = None
    pattern: str = "alternate"
    centre: Optional[tuple[float, float]] = None
    radius: Optional[float] = Field(None, allow_inf_nan=False)
    inner_radius: Optional[float] = Field(None, allow_inf_nan=False)
    rings: Optional[int] = None
    file: Optional[str] = None
    scale: float = Field(1.0, gt=0, allow_inf_nan=False,
                         description="factor applied to the mesh coordinates (1e-3: mm)")

    #: the keys each source takes (besides scale)
    KEYS: ClassVar[dict] = {"rectangle": ("origin", "size", "divisions", "pattern"),
                            "box": ("origin", "size", "divisions"),
                            "disc": ("centre", "radius", "rings"),
                            "annulus": ("centre", "radius", "inner_radius", "rings"),
                            None: ("file",)}

    @model_validator(mode="after")
    def _one_source(self):
        if (self.generator is None) == (self.file is None):
            raise ValueError("give either generator = \"rectangle\", \"box\", \"disc\" or "
                             "\"annulus\", or file = \"path\"")
        # a key of another source is a mistake (inner_radius with a disc would otherwise
        # silently give a full disc)
        takes = self.KEYS[self.generator]
        fields = type(self).model_fields
        stray = sorted(k for k in set(self.model_fields_set) - set(takes) - {"generator", "scale"}
                       if getattr(self, k) != fields[k].default)   # a dumped default is no key
        if stray:
            source = f'generator "{self.generator}"' if self.generator else "a mesh file"
            raise ValueError(f"{', '.join(stray)} does not apply to {source}, which takes "
                             f"{', '.join(takes)}")
        if self.generator in ("rectangle", "box"):
            d, count = (2, "two") if self.generator == "rectangle" else (3, "three")
            for key in ("origin", "size", "divisions"):
                value = getattr(self, key)
                if value is None:
                    raise ValueError(f"{self.generator} needs {key}")
                if len(value) != d:
                    raise ValueError(f"{self.generator} takes {key} of {d} components, got "
                                     f"{len(value)}")
            if not all(map(math.isfinite, self.origin)):
                raise ValueError("origin must be finite")
            if min(self.size) <= 0 or not all(map(math.isfinite, self.size)):
                raise ValueError(f"size must be {count} positive lengths")
            if min(self.divisions) < 1:
                raise ValueError(f"divisions must be {count} positive integers")
            if self.pattern not in DIAGONAL_PATTERNS:
                raise ValueError(f"pattern must be one of {', '.join(DIAGONAL_PATTERNS)}")
        if self.generator in ("disc", "annulus"):
            for key in self.KEYS[self.generator]:
                if getattr(self, key) is None:
                    raise ValueError(f"{self.generator} needs {key}")
            if self.radius <= 0:
                raise ValueError("radius must be a positive length")
            if self.rings < 1:
                raise ValueError("rings must be a positive integer")
            if self.generator == "annulus" and not 0 < self.inner_radius < self.radius:
                raise ValueError("inner_radius must be positive and below radius")
        return self


class VelocityComponents(_Strict):
    x: Optional[Load] = None
    y: Optional[Load] = None
    z: Optional[Load] = None

    _finite = field_validator("x", "y", "z")(classmethod(lambda cls, v: _finite_load(v)))

    def components(self, dim: int) -> tuple:
        """The prescribed value of each of the ``dim`` components (None: not prescribed)."""
        return (self.x, self.y, self.z)[:dim]


class BoundarySpec(_Strict):
    region: str
    velocity: Optional[VelocityComponents] = None
    traction: Optional[LoadVector] = None
    amplitude: Optional[list[tuple[float, float]]] = Field(None, min_length=1)

    @model_validator(mode="after")
    def _one_condition(self):
        if self.velocity is None and self.traction is None:
            raise ValueError("give velocity = { x = ..., y = ... } or traction = [tx, ty]")
        if self.velocity is not None and all(
                c is None for c in (self.velocity.x, self.velocity.y, self.velocity.z)):
            raise ValueError("velocity needs at least one of x, y, z")
        if self.traction is not None:
            for value in self.traction:
                _finite_load(value)
        if self.velocity is not None and self.traction is not None:
            # a prescribed velocity wins per component (docs/case-file.md): a traction given
            # on a held component would be dropped without a word
            held = (self.velocity.x, self.velocity.y, self.velocity.z)
            for i, (h, t) in enumerate(zip(held, self.traction)):
                if h is not None and not (isinstance(t, (int, float)) and t == 0):
                    axis = "xyz"[i]
                    raise ValueError(
                        f"traction[{i}] acts along {axis}, which velocity.{axis} holds: a "
                        f"prescribed velocity wins per component, so this traction would be "
                        f"ignored (give 0 there, or drop velocity.{axis})")
        if self.amplitude is not None:
            _check_amplitude(self.amplitude)
        return self


def _check_amplitude(table):
    times = [t for t, _ in table]
    if not all(math.isfinite(t) and math.isfinite(a) for t, a in table):
        raise ValueError("amplitude: times and values must be finite")
    if any(b <= a for a, b in zip(times, times[1:])):
        raise ValueError("amplitude: times must increase strictly, [[t0, a0], [t1, a1], ...]")


class BodySpec(_Strict):
    name: str = Field(min_length=1)
    material: str
    velocity: Any = None              # at rest unless given
    mesh: MeshSpec
    boundary: list[BoundarySpec] = []
    body_force: Optional[LoadVector] = Field(None, description="acceleration, m/s^2 (seed "
                                             "eq. 9a's f_R per unit mass), e.g. gravity")

    @field_validator("body_force")
    @classmethod
    def _finite_body_force(cls, value):
        for item in value or ():
            _finite_load(item)
        return value

    @field_validator("velocity")
    @classmethod
    def _velocity(cls, value):
        if value is None or callable(value):
            return value
        if isinstance(value, (list, tuple)) and len(value) in (2, 3):
            for item in value:
                if isinstance(item, bool) or not isinstance(item, (int, float, str)):
                    raise ValueError("each component must be a number or an expression string")
                if isinstance(item, (int, float)) and not math.isfinite(item):
                    raise ValueError("components must be finite")
            return tuple(value)
        raise ValueError("expected [vx, vy] (numbers or expressions of x and y; [vx, vy, vz] "
                         "of x, y, z in 3D) or, from Python, a callable of the (n, d) "
                         "reference points")


class WallSpec(_Strict):
    point: Vector
    normal: Vector
    velocity: Optional[Vector] = None

    @model_validator(mode="after")
    def _normal(self):
        if self.velocity is None:
            self.velocity = [0.0] * len(self.point)
        values = (*self.point, *self.normal, *self.velocity)
        if not all(map(math.isfinite, values)):
            raise ValueError("point, normal and velocity must be finite")
        length = math.hypot(*self.normal)
        if length == 0.0:
            raise ValueError("normal must not be zero")
        # stored as a unit vector: a tiny but valid length (1e-170) must not underflow later
        self.normal = [n / length for n in self.normal]
        return self


class ContactSpec(_Strict):
    model_config = ConfigDict(extra="forbid", populate_by_name=True)

    bodies: Union[list[str], Literal["all"]] = Field(min_length=1)
    self_contact: bool = Field(False, alias="self")
    model: Literal["stick", "slip", "coulomb"] = "slip"
    friction: Optional[float] = Field(None, ge=0, allow_inf_nan=False,
                                      description="Coulomb coefficient mu (model coulomb)")
    wall: Optional[WallSpec] = None
    regions: Optional[list[str]] = Field(None, min_length=1)

    @property
    def friction_coefficient(self) -> float:
        """mu of the contact law: 0 for slip, infinite for stick."""
        return {"slip": 0.0, "stick": math.inf}.get(self.model, self.friction)

    @model_validator(mode="after")
    def _partner(self):
        if self.bodies == "all" or len(self.bodies) > 2:
            if self.wall is not None or self.self_contact:
                raise ValueError("several bodies (or \"all\") pair each with each; a wall "
                                 "or self-contact takes one body")
        elif self.self_contact:
            if len(self.bodies) != 1 or self.wall is not None:
                raise ValueError("self = true takes exactly one body and no wall")
        if self.model == "coulomb" and self.friction is None:
            raise ValueError("model = \"coulomb\" needs friction = mu (>= 0)")
        if self.model != "coulomb" and self.friction is not None:
            raise ValueError(f"friction is the coefficient of model = \"coulomb\" (model "
                             f"\"{self.model}\" has none)")
        if self.bodies == "all" or len(self.bodies) > 2 or self.self_contact:
            return self
        if self.wall is None and len(self.bodies) != 2:
            raise ValueError("give two bodies, one body and a wall = { point, normal }, or one "
                             "body and self = true")
        if self.wall is not None and len(self.bodies) != 1:
            raise ValueError("a wall contact takes exactly one body")
        if len(self.bodies) == 2 and self.bodies[0] == self.bodies[1]:
            raise ValueError("name two different bodies (self = true for a body against "
                             "itself)")
        return self


class OutputSpec(_Strict):
    history_every: int = Field(1, ge=1, description="a history row every N steps (and the "
                               "last step)")
    fields: Optional[list[str]] = Field(None, description="point fields of the frames "
                                        "(default: all)")
    keep_checkpoints: int = Field(3, ge=1, description="how many of the newest checkpoints "
                                  "a run keeps (a restart falls back to an older one when the "
                                  "newest is damaged); older ones are deleted as new ones "
                                  "are written")

    @field_validator("fields")
    @classmethod
    def _known_fields(cls, value):
        for name in value or ():
            if name not in FIELDS:
                close = difflib.get_close_matches(name, list(FIELDS), n=1)
                hint = f"did you mean {close[0]!r}? " if close else ""
                raise ValueError(f"unknown field {name!r} ({hint}valid: {', '.join(FIELDS)})")
        return value


class CaseSpec(_Strict):
    title: Optional[str] = None

    @field_validator("title")
    @classmethod
    def _printable_title(cls, value):
        if value is not None and not value.isprintable():
            raise ValueError("must not contain control characters (newlines, escape codes)")
        return value
    run: RunSettings
    material: list[MaterialSpec] = Field(min_length=1)
    body: list[BodySpec] = Field(min_length=1)
    contact: list[ContactSpec] = []
    output: OutputSpec = OutputSpec()


class Body:
    """A validated body: its mesh, material, initial velocity and boundary conditions."""

    def __init__(self, spec: BodySpec, material: Material, mesh: Mesh, velocity):
        self.spec = spec
        self.name = spec.name
        self.material = material
        self.mesh = mesh
        self.initial_velocity = velocity  # callable (n,2) -> (n,2)
        self.boundary = spec.boundary


class Case:
    """A validated case; ``bodies`` hold read and checked meshes."""

    def __init__(self, spec: CaseSpec, base_dir: Path, source: str):
        self.spec = spec
        self.base_dir = base_dir
        self.source = source
        self.title = spec.title
        self.run = spec.run
        self.materials = {m.name: Material(m.name, m.model, m.density, m.youngs_modulus,
                                           m.poisson_ratio) for m in spec.material}
        self.bodies: list[Body] = []
        self.contacts = spec.contact
        self.output = spec.output

    @property
    def stem(self) -> str:
        return Path(self.source).stem if self.source.endswith(".toml") else "case"


def load_case(source: Union[str, Path, dict], base_dir: Union[str, Path, None] = None,
              overrides=None) -> Case:
    """Read and validate a case from a TOML path or a dict; raise InputError on any problem.

    ``overrides``: ``KEY=VALUE`` texts (the CLI's ``--set``, impactfv.overrides) applied to
    the data before it is validated."""
    if isinstance(source, dict):
        data, name = source, "<dict>"
        base = Path(base_dir) if base_dir is not None else Path.cwd()
    else:
        path = Path(source)
        name = str(path)
        if not path.is_file():
            raise InputError(f"{path}: case file not found")
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"{path}: invalid TOML ({exc})") from None
        except RecursionError:
            raise InputError(f"{path}: invalid TOML (arrays or tables nested too deeply)") \
                from None
        except UnicodeDecodeError:
            raise InputError(f"{path}: not a UTF-8 text file") from None
        except OSError as exc:
            raise InputError(f"{path}: cannot read the case file "
                             f"({exc.strerror or exc})") from None
        base = Path(base_dir) if base_dir is not None else path.resolve().parent
    overridden = set()
    if overrides:
        from .overrides import apply
        data, overridden = apply(data, overrides, CaseSpec, name)
    _refuse_booleans(data, name)
    try:
        spec = CaseSpec.model_validate(data)
    except ValidationError as exc:
        raise InputError(_one_line(exc, name, overridden)) from None
    case = Case(spec, base, name)
    _check_names(spec, name)
    _refuse_meshes_too_large(spec, name)
    dim = None
    for i, b in enumerate(spec.body):
        mesh = _build_mesh(b.mesh, base, f"{name}: body[{i}].mesh")
        if dim is None:
            dim = mesh.dim
        elif mesh.dim != dim:
            raise InputError(f"{name}: body[{i}].mesh: a {mesh.dim}D mesh in a case whose "
                             f"first body is {dim}D (all bodies must have the same dimension)")
        _check_lengths(b, i, dim, name)
        for j, bc in enumerate(b.boundary):
            if bc.region not in mesh.regions:
                raise InputError(f"{name}: body[{i}].boundary[{j}].region: "
                                 f"{_unknown_region(bc.region, [mesh])}")
        velocity = _velocity_function((0.0,) * dim if b.velocity is None else b.velocity,
                                      f"{name}: body[{i}].velocity", dim)
        case.bodies.append(Body(b, case.materials[b.material], mesh, velocity))
    if dim == 3 and spec.run.method != "fv":
        raise InputError(f"{name}: run.method: the finite element baselines (fem-t3, "
                         f"fem-q4md) are 2D only; a 3D mesh runs with method = \"fv\"")
    for k, c in enumerate(spec.contact):
        if c.wall is not None:
            for key in ("point", "normal", "velocity"):
                _check_length(getattr(c.wall, key), dim, f"{name}: contact[{k}].wall.{key}")
    meshes = {b.name: b.mesh for b in case.bodies}
    case.contacts = _pairs(spec.contact, [b.name for b in spec.body], name)
    for k, c in enumerate(spec.contact):
        names = list(meshes) if c.bodies == "all" else c.bodies
        known = set().union(*(meshes[n].regions for n in names))
        for region in c.regions or ():
            if region not in known:
                raise InputError(f"{name}: contact[{k}].regions: "
                                 f"{_unknown_region(region, [meshes[n] for n in names])}")
    return case


def _pairs(contacts, body_names, source) -> list:
    """The contacts of a case, one per pair: an entry of more than two bodies (or "all")
    stands for every pair of them, in order (a, b), (a, c), (b, c), ...; the history numbers
    these pairs (contact0, contact1, ...)."""
    from itertools import combinations

    out = []
    for k, c in enumerate(contacts):
        names = body_names if c.bodies == "all" else c.bodies
        if c.bodies == "all" or len(names) > 2:
            if len(names) < 2:
                raise InputError(f"{source}: contact[{k}].bodies: \"all\" needs at least two "
                                 "bodies")
            out += [c.model_copy(update={"bodies": list(p)}) for p in combinations(names, 2)]
        else:
            out.append(c)
    return out


def _check_length(vector, dim: int, key: str):
    if vector is not None and len(vector) != dim:
        raise InputError(f"{key}: expected {dim} components for a {dim}D mesh, got "
                         f"{len(vector)}")


def _check_lengths(body: BodySpec, i: int, dim: int, source: str):
    """Every vector of a body has as many components as its mesh has dimensions, and its
    load expressions are valid."""
    if body.velocity is not None and not callable(body.velocity):
        _check_length(body.velocity, dim, f"{source}: body[{i}].velocity")
    _check_length(body.body_force, dim, f"{source}: body[{i}].body_force")
    names = LOAD_VARIABLES[:dim] + ("t",)
    for c, item in zip("xyz", body.body_force or ()):
        if isinstance(item, str):
            compile_expression(item, f"{source}: body[{i}].body_force.{c}", names)
    for j, bc in enumerate(body.boundary):
        key = f"{source}: body[{i}].boundary[{j}]"
        if bc.velocity is not None:
            for c, item in zip("xyz", bc.velocity.components(3)):
                if isinstance(item, str):
                    compile_expression(item, f"{key}.velocity.{c}", names)
        for c, item in zip("xyz", bc.traction or ()):
            if isinstance(item, str):
                compile_expression(item, f"{key}.traction.{c}", names)
    for j, bc in enumerate(body.boundary):
        key = f"{source}: body[{i}].boundary[{j}]"
        _check_length(bc.traction, dim, key + ".traction")
        if bc.velocity is not None and dim == 2 and bc.velocity.z is not None:
            raise InputError(f"{key}.velocity.z: a 2D mesh has no z component")


def _unknown_region(region: str, meshes) -> str:
    """Why ``region`` names none of the regions of ``meshes``, and which they have."""
    known = sorted(set().union(*(m.regions for m in meshes)))
    for m in meshes:
        if region in m.skipped_sets:
            return (f"{region!r} is a {m.skipped_sets[region]}, not a boundary region (the "
                    f"mesh has: {', '.join(known) or 'none'})")
    close = difflib.get_close_matches(region, known, n=1)
    hint = f"did you mean {close[0]!r}? " if close else ""
    return f"unknown region {region!r} ({hint}the mesh has: {', '.join(known) or 'none'})"


#: the keys that take true/false
BOOLEAN_KEYS = ("self",)


def _refuse_booleans(data, source: str, path: str = ""):
    """No key of a case but ``contact.self`` takes true/false, and pydantic would read
    them as 1/0."""
    items = data.items() if isinstance(data, dict) else \
        enumerate(data) if isinstance(data, (list, tuple)) else ()
    for key, value in items:
        where = f"{path}[{key}]" if isinstance(key, int) else f"{path}.{key}" if path else key
        if isinstance(value, bool):
            if key in BOOLEAN_KEYS and isinstance(data, dict) and path.startswith("contact["):
                continue
            raise InputError(f"{source}: {where}: expected a number or text, got "
                             f"{str(value).lower()} (only contact.self takes a boolean)")
        _refuse_booleans(value, source, where)


def _refuse_meshes_too_large(spec: CaseSpec, source: str):
    """Generated meshes whose run cannot fit in the memory available are refused before
    they are built (their sizes follow from divisions or rings)."""
    from .memory import counts_of_generator, estimate, memory_problem

    in_contact = {name for c in spec.contact
                  for name in ([b.name for b in spec.body] if c.bodies == "all" else c.bodies)}
    counts = [(i, counts_of_generator(b.mesh, b.name in in_contact))
              for i, b in enumerate(spec.body)]
    known = [(i, c) for i, c in counts if c is not None]
    if not known:
        return
    dim = 3 if any(spec.body[i].mesh.generator == "box" for i, _ in known) else 2
    problem = memory_problem(estimate([c for _, c in known], spec.run.order,
                                      spec.run.geometric_flux == "upwind", len(spec.contact),
                                      dim=dim, relaxed=spec.run.compatibility_time > 0))
    if problem:
        i, largest = max(known, key=lambda item: item[1].nodes)
        mesh = spec.body[i].mesh
        key, value = ("rings", mesh.rings) if mesh.generator in ("disc", "annulus") \
            else ("divisions", list(mesh.divisions))
        raise InputError(f"{source}: body[{i}].mesh.{key}: {value} makes "
                         f"{largest.nodes:,} nodes; the run {problem}")


def _check_column_name(name: str, key: str):
    """Body and region names become history.csv column names: no comma, quote or control
    character, which would break the CSV."""
    bad = [ch for ch in name if ch in ',"' or not ch.isprintable()]
    if bad:
        raise InputError(f"{key}: {name!r} contains {bad[0]!r}; names become history.csv "
                         "columns, so commas, quotes and control characters are not allowed")


def _check_names(spec: CaseSpec, source: str):
    seen = set()
    for i, m in enumerate(spec.material):
        if m.name in seen:
            raise InputError(f"{source}: material[{i}].name: duplicated name {m.name!r}")
        seen.add(m.name)
    bodies = set()
    for i, b in enumerate(spec.body):
        _check_column_name(b.name, f"{source}: body[{i}].name")
        for j, entry in enumerate(b.boundary):
            _check_column_name(entry.region, f"{source}: body[{i}].boundary[{j}].region")
        if b.name in bodies:
            raise InputError(f"{source}: body[{i}].name: duplicated name {b.name!r}")
        bodies.add(b.name)
        if b.material not in seen:
            raise InputError(f"{source}: body[{i}].material: unknown material {b.material!r} "
                             f"(defined: {', '.join(sorted(seen))})")
    for i, c in enumerate(spec.contact):
        for name in (() if c.bodies == "all" else c.bodies):
            if name not in bodies:
                raise InputError(f"{source}: contact[{i}].bodies: unknown body {name!r} "
                                 f"(defined: {', '.join(sorted(bodies))})")


def _build_mesh(spec: MeshSpec, base: Path, key: str) -> Mesh:
    if spec.generator == "rectangle":
        mesh = rectangle(spec.origin, spec.size, spec.divisions, spec.pattern)
        source = key
    elif spec.generator == "box":
        mesh = box(spec.origin, spec.size, spec.divisions)
        source = key
    elif spec.generator == "disc":
        mesh = disc(spec.centre, spec.radius, spec.rings)
        source = key
    elif spec.generator == "annulus":
        mesh = annulus(spec.centre, spec.radius, spec.inner_radius, spec.rings)
        source = key
    else:
        path = Path(spec.file)
        if not path.is_absolute():
            path = base / path
        mesh = read_mesh(path)
        source = str(path)
    if spec.scale != 1.0:
        mesh.points = np.asarray(mesh.points, dtype=float) * spec.scale
    return validate_and_orient(mesh, source)


def _velocity_function(value, key, dim=2):
    if callable(value):
        def evaluate(points):
            try:
                out = np.asarray(value(points), dtype=float)
            except Exception as exc:
                raise InputError(f"{key}: the velocity callable failed ({exc})") from None
            if out.shape != points.shape or not np.all(np.isfinite(out)):
                raise InputError(f"{key}: the velocity callable must return finite values of "
                                 f"shape {points.shape}")
            return out
        return evaluate
    parts = []
    names = "xyz"[:dim]
    for c, item in zip(names, value):
        if isinstance(item, str):
            parts.append(compile_expression(item, f"{key}.{c}", tuple(names)))
        else:
            parts.append(lambda *x, _v=float(item): np.full(np.shape(x[0]), _v))

    def evaluate(points):
        out = np.column_stack([f(*points.T) for f in parts])
        if not np.all(np.isfinite(out)):
            raise InputError(f"{key}: the expression gives non-finite values on the mesh")
        return out
    return evaluate


# ------------------------------------------------------------------------------ error text

def _one_line(exc: ValidationError, source: str, overridden=()) -> str:
    errors = exc.errors()
    # a misspelt key also makes the right one "missing": report the unknown key first
    err = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
    loc = err["loc"]
    path = _format_loc(loc)
    if any(path == k or path.startswith(k + ".") or path.startswith(k + "[")
           for k in overridden):
        path = f"--set {path}"
    kind = err["type"]
    if kind == "extra_forbidden":
        model = _model_at(CaseSpec, loc[:-1])
        hint = ""
        if model is not None:
            close = difflib.get_close_matches(str(loc[-1]), list(model.model_fields), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else \
                f" (expected one of: {', '.join(model.model_fields)})"
        return f"{source}: {path}: unknown key{hint}"
    if kind == "missing":
        return f"{source}: {path}: required key is missing"
    msg = err["msg"]
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, "):]
    got = err.get("input")
    shown = "" if isinstance(got, dict) or got is None else f", got {got!r}"
    return f"{source}: {path}: {msg[0].lower() + msg[1:]}{shown}"


def _format_loc(loc) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "<top level>"


def _model_at(model, loc):
    for part in loc:
        if isinstance(part, int):
            continue
        field = model.model_fields.get(part)
        if field is None:
            return None
        model = _unwrap_model(field.annotation)
        if model is None:
            return None
    return model


def _unwrap_model(annotation):
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    if get_origin(annotation) is not None:
        for arg in get_args(annotation):
            found = _unwrap_model(arg)
            if found is not None:
                return found
    return None
