"""``impactfv plot RESULT_DIR``: PNG quick-look pictures of a result folder, no ParaView
needed.

* ``<field>.png``: a field (default pressure) on the deformed bodies at a few times, read
  back from the ``fields_*.vtu`` frames (reference points + displacement), one shared
  colour scale, the rigid walls drawn where the case has them;
* ``histories.png``: from ``history.csv``, the energies and, for each contact, the contact
  force on its first body and the smallest gap.

Units are SI with a prefix chosen from the values (MPa, kJ/m, us); in 2D (plane strain)
forces and energies are per metre of thickness and the labels say so. Written into
``RESULT_DIR/plots`` (or ``-o``).
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .errors import InputError

PREFIXES = ((1e9, "G"), (1e6, "M"), (1e3, "k"), (1.0, ""), (1e-3, "m"), (1e-6, "\u00b5"),
            (1e-9, "n"))
FONT = {"font.size": 11, "axes.titlesize": 11, "axes.labelsize": 11, "legend.fontsize": 10,
        "xtick.labelsize": 10, "ytick.labelsize": 10}
#: meanings shown in colour-bar labels
MEANING = {"pressure": "pressure (compression positive)", "von_mises": "von Mises stress",
           "J": "J = det F", "contact_pressure": "contact pressure",
           "contact_status": "contact status (0 open, 1 stick, 2 slip)",
           "body": "body index"}
#: unit of each field; components and magnitudes take their field's unit
UNITS = {"pressure": "Pa", "von_mises": "Pa", "stress": "Pa", "contact_pressure": "Pa",
         "velocity": "m/s", "displacement": "m", "J": "", "body": "", "contact_status": ""}


def prefixed(values, unit: str, keep=("m/s", "")) -> tuple[float, str]:
    """(factor, unit label): values / factor read well in the prefixed unit (kPa .. GPa,
    kJ/m, mm, us); units in ``keep`` are left alone."""
    if unit in keep:
        return 1.0, unit
    finite = np.abs(np.asarray(values, float))
    finite = finite[np.isfinite(finite)]
    big = float(finite.max()) if len(finite) else 0.0
    if big == 0.0:
        return 1.0, unit
    for factor, prefix in PREFIXES:
        if big >= factor:
            return factor, prefix + unit
    return PREFIXES[-1][0], PREFIXES[-1][1] + unit


def read_pvd(path: Path) -> list[tuple[float, str]]:
    """(time, file) of each data set of a ParaView collection."""
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        raise InputError(f"{path}: unreadable ParaView collection ({exc})") from None
    entries = []
    for k, d in enumerate(root.iter("DataSet")):
        try:
            time = float(d.get("timestep"))
        except (TypeError, ValueError):
            raise InputError(f"{path}: data set {k} has no valid timestep "
                             f"({d.get('timestep')!r})") from None
        if not d.get("file"):
            raise InputError(f"{path}: data set {k} names no file")
        entries.append((time, d.get("file")))
    return entries


def pick_frames(frames, times=None, count=4) -> list[int]:
    """Indices of the frames nearest to ``times``, or ``count`` frames spread from the first
    to the last."""
    if not frames:
        return []
    t = np.array([f[0] for f in frames])
    if times:
        return list(dict.fromkeys(int(np.argmin(np.abs(t - x))) for x in times))
    k = min(count, len(frames))
    return list(dict.fromkeys(np.linspace(0, len(frames) - 1, k).round().astype(int).tolist()))


def field_values(point_data: dict, name: str, where: str) -> tuple[np.ndarray, str, str]:
    """(values, unit, label) of ``name``: a scalar field, a vector's magnitude, or a
    component (velocity_x, displacement_y, stress_xx, stress_xy ...)."""
    components = {"xx": 0, "yy": 1, "zz": 2, "xy": 3, "yz": 4, "xz": 5}
    if name in point_data:
        v = np.asarray(point_data[name], float)
        base = name
        if v.ndim == 2 and v.shape[1] == 6:
            raise InputError(f"{where}: --field {name}: a tensor; give a component "
                             f"({', '.join(f'{name}_{c}' for c in components)})")
        if v.ndim == 2:
            v, label = np.linalg.norm(v, axis=1), f"|{name}|"
        else:
            label = MEANING.get(name, name)
    else:
        base, _, comp = name.rpartition("_")
        v = point_data.get(base)
        if v is None:
            raise InputError(f"{where}: no field {name!r} (the frames have: "
                             f"{', '.join(sorted(point_data))}; vectors also as NAME_x, "
                             "NAME_y, tensors as NAME_xx, NAME_xy ...)")
        v = np.asarray(v, float)
        index = components.get(comp) if v.ndim == 2 and v.shape[1] == 6 else \
            "xyz".find(comp) if len(comp) == 1 else -1
        if index is None or index < 0:
            raise InputError(f"{where}: --field {name}: {base} has no component {comp!r}")
        v, label = v[:, index], f"{base} {comp}"
    return v, UNITS.get(base, ""), label


def _mesh_triangles(mesh, where):
    import meshio  # noqa: F401  (the reader of the frames)

    from .mesh.generators import quads_to_triangles

    tris = []
    for block in mesh.cells:
        if block.type == "triangle":
            tris.append(block.data)
        elif block.type == "quad":
            tris.append(quads_to_triangles(block.data))
        else:
            raise InputError(f"{where}: cells of type {block.type!r}: impactfv plot draws 2D "
                             "results (triangles, quads); open 3D results in ParaView")
    return np.concatenate(tris)


def _read_frame(path: Path):
    import meshio

    if not path.is_file():
        raise InputError(f"{path}: frame listed in fields.pvd is missing")
    try:
        return meshio.read(path)
    except Exception as exc:  # meshio raises many types
        raise InputError(f"{path}: unreadable frame ({exc})") from None


def field_picture(folder: Path, out: Path, field="pressure", times=None) -> Path:
    """``out/<field>.png``: ``field`` on the deformed bodies at the frames nearest to
    ``times`` (default four frames), shared colour scale."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.tri import Triangulation

    frames = read_pvd(folder / "fields.pvd")
    chosen = pick_frames(frames, times)
    if not chosen:
        raise InputError(f"{folder / 'fields.pvd'}: no frames")
    walls = read_pvd(folder / "walls.pvd") if (folder / "walls.pvd").is_file() else []
    shots = []
    for k in chosen:
        t, name = frames[k]
        mesh = _read_frame(folder / name)
        where = str(folder / name)
        if mesh.points.shape[1] == 3 and np.ptp(mesh.points[:, 2]) > 0:
            raise InputError(f"{where}: 3D points: impactfv plot draws 2D results; open 3D "
                             "results in ParaView")
        x = mesh.points[:, :2] + (mesh.point_data["displacement"][:, :2]
                                  if "displacement" in mesh.point_data else 0.0)
        values, unit, label = field_values(mesh.point_data, field, where)
        wall = None
        if k < len(walls) and (folder / walls[k][1]).is_file():
            wall = _read_frame(folder / walls[k][1])
        shots.append((t, x, _mesh_triangles(mesh, where), values, wall,
                      "displacement" in mesh.point_data))
    allv = np.concatenate([s[3] for s in shots])
    lo, hi = np.nanpercentile(allv, [0.5, 99.5]) if len(allv) else (0.0, 1.0)
    signed = lo < 0 < hi and field not in ("J",)
    if signed:
        lo, hi = -max(abs(lo), abs(hi)), max(abs(lo), abs(hi))
    if hi <= lo:
        lo, hi = lo - 0.5 * abs(lo or 1.0), hi + 0.5 * abs(hi or 1.0)
    factor, unit_label = prefixed([lo, hi], unit)
    pts = np.concatenate([s[1] for s in shots])
    lfactor, lunit = prefixed(np.ptp(pts, axis=0), "m")
    tfactor, tunit = prefixed([shots[-1][0] or 1.0], "s")
    span = np.ptp(pts, axis=0)
    aspect = span[1] / span[0] if span[0] > 0 else 1.0
    n = len(shots)
    stacked = aspect < 0.6
    with plt.rc_context(FONT):
        if stacked:
            fig, axes = plt.subplots(n, 1, figsize=(9, n * (7.0 * aspect + 0.8) + 0.7),
                                     sharex=True, sharey=True, constrained_layout=True)
        else:
            a = min(max(aspect, 0.6), 2.0)
            fig, axes = plt.subplots(1, n, figsize=(3.4 * n + 1.6, 3.4 * a + 1.2),
                                     sharex=True, sharey=True, constrained_layout=True)
        axes = np.atleast_1d(axes)
        cmap = "RdBu_r" if signed else "viridis"
        for ax, (t, x, tri, values, wall, deformed) in zip(axes, shots):
            triangulation = Triangulation(x[:, 0] / lfactor, x[:, 1] / lfactor, tri)
            im = ax.tripcolor(triangulation, values / factor, shading="gouraud", cmap=cmap,
                              vmin=lo / factor, vmax=hi / factor, rasterized=True)
            if wall is not None:
                for block in wall.cells:
                    for seg in block.data:
                        p = wall.points[seg][:, :2] / lfactor
                        ax.plot(p[:, 0], p[:, 1], color="k", lw=3, solid_capstyle="butt")
            ax.set_aspect("equal")
            ax.set_title(f"t = {t / tfactor:.4g} {tunit}" + ("" if deformed else
                                                             " (undeformed)"))
        for ax in axes[-1:] if stacked else axes:
            ax.set_xlabel(f"x ({lunit})")
        for ax in axes if stacked else axes[:1]:
            ax.set_ylabel(f"y ({lunit})")
        cb = fig.colorbar(im, ax=list(axes), shrink=0.9 if stacked else 0.8,
                          extend="both" if len(allv) else "neither")
        cb.set_label(f"{label} ({unit_label})" if unit_label else label)
        out.mkdir(parents=True, exist_ok=True)
        path = out / f"{field}.png"
        fig.savefig(path, dpi=130)
        plt.close(fig)
    return path


def read_history(path: Path) -> dict[str, np.ndarray]:
    try:
        with open(path) as fh:
            names = fh.readline().strip().split(",")
        table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: unreadable history ({exc})") from None
    if table.shape[1] != len(names) or "time" not in names:
        raise InputError(f"{path}: not a history.csv of impactfv run")
    return {name: table[:, k] for k, name in enumerate(names)}


def history_picture(folder: Path, out: Path) -> Path:
    """``out/histories.png``: energies; per contact the force on its first body and the
    smallest gap."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h = read_history(folder / "history.csv")
    summary = {}
    if (folder / "summary.json").is_file():
        try:
            summary = json.loads((folder / "summary.json").read_text())
        except (OSError, ValueError):
            summary = {}
        if not isinstance(summary, dict):
            summary = {}             # damaged: the pictures do without its names
    plane = "momentum_z" not in h
    per = ", per metre of thickness" if plane else ""
    contacts = sorted({int(k[len("contact"):].split("_")[0]) for k in h
                       if k.startswith("contact") and k.endswith("_gap")})
    described = summary.get("contacts") or []
    bodies = summary.get("bodies") or []
    t = h["time"]
    tfactor, tunit = prefixed([t[-1] if len(t) else 1.0], "s")
    rows = 1 + 2 * bool(contacts)
    with plt.rc_context(FONT):
        fig, axes = plt.subplots(rows, 1, figsize=(9, 3.4 * rows + 0.4), sharex=True,
                                 constrained_layout=True)
        axes = np.atleast_1d(axes)
        energy = [("kinetic_energy", "kinetic"), ("strain_energy", "strain"),
                  ("total_energy", "total (kinetic + strain)" if "contact_energy" not in h
                   else "total (kinetic + strain + absorbed by contact)"),
                  ("contact_energy", "absorbed by the contact")]
        efactor, eunit = prefixed(np.concatenate([h[k] for k, _ in energy if k in h]),
                                  "J/m" if plane else "J")
        for (key, label), style in zip(energy, ("--", ":", "-", "-.")):
            if key in h:
                axes[0].plot(t / tfactor, h[key] / efactor, ls=style, lw=1.8, label=label)
        axes[0].set_ylabel(f"energy ({eunit}{per})")
        axes[0].legend(loc="best")
        axes[0].grid(alpha=0.3)
        if contacts:
            comps = [c for c in "xyz" if f"contact{contacts[0]}_f{c}" in h]
            forces = np.concatenate([h[f"contact{k}_f{c}"] for k in contacts for c in comps])
            ffactor, funit = prefixed(forces, "N/m" if plane else "N")
            gaps = np.concatenate([h[f"contact{k}_gap"] for k in contacts])
            gfactor, gunit = prefixed(gaps, "m")
            for k in contacts:
                info = described[k] if k < len(described) else {}
                names = info.get("bodies") or []
                partner = "the wall" if info.get("wall") else \
                    (repr(names[1]) if len(names) > 1 else "?")
                first = repr(names[0]) if names else "the first body"
                who = f"contact {k}: on {first} from {partner}"
                for c, style in zip(comps, ("-", "--", ":")):
                    axes[1].plot(t / tfactor, h[f"contact{k}_f{c}"] / ffactor, ls=style,
                                 lw=1.6, label=f"{who}, {c} component")
                axes[2].plot(t / tfactor, h[f"contact{k}_gap"] / gfactor, lw=1.6,
                             label=f"contact {k}" + (f" ({', '.join(names)})" if names else ""))
            axes[1].set_ylabel(f"contact force ({funit}{per})")
            axes[1].legend(loc="best")
            axes[1].grid(alpha=0.3)
            axes[2].axhline(0.0, color="k", lw=0.8)
            axes[2].set_ylabel(f"smallest gap ({gunit}); < 0: overlap")
            axes[2].legend(loc="best")
            axes[2].grid(alpha=0.3)
        axes[-1].set_xlabel(f"time ({tunit})")
        title = summary.get("title") or ""
        if title or bodies:
            fig.suptitle(title or ", ".join(bodies))
        out.mkdir(parents=True, exist_ok=True)
        path = out / "histories.png"
        fig.savefig(path, dpi=130)
        plt.close(fig)
    return path


def plot_results(folder, out=None, field="pressure", times=None) -> list[Path]:
    """Write the pictures of result folder ``folder`` into ``out`` (default
    ``folder/plots``); returns their paths."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: no such result folder")
    has_frames = (folder / "fields.pvd").is_file()
    has_history = (folder / "history.csv").is_file()
    if not (has_frames or has_history):
        raise InputError(f"{folder}: not a result folder of impactfv run (no fields.pvd, "
                         "no history.csv)")
    out = Path(out) if out is not None else folder / "plots"
    written = []
    if has_frames:
        written.append(field_picture(folder, out, field, times))
    if has_history:
        written.append(history_picture(folder, out))
    return written


def parse_times(text: str | None):
    if text is None:
        return None
    try:
        times = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise InputError(f"--times: expected times in seconds separated by commas, got "
                         f"{text!r}") from None
    if not times or not all(math.isfinite(x) and x >= 0 for x in times):
        raise InputError(f"--times: expected non-negative times in seconds, got {text!r}")
    return times


def plot_main(args) -> int:
    from .errors import printable

    written = plot_results(args.results, args.output, args.field, parse_times(args.times))
    print(f"wrote {', '.join(printable(str(p)) for p in written)}")
    return 0
