"""Abaqus ``.inp`` meshes: nodes, 2D solid elements and the named sets a model defines.

meshio reads ``.inp`` files too, but without ``*SURFACE`` and without the plane-strain
element types (CPE3, CPE4, CPE4R): what an Abaqus user of a plane-strain code has. This
reader takes the mesh part of a flat input file or of a single part and its instance:

* ``*NODE`` (2 or 3 coordinates; ``NSET=`` makes a node set of the block);
* ``*ELEMENT, TYPE=...`` (``ELSET=`` makes an element set of the block): linear triangles
  (CPE3, CPS3, CPEG3 and their H variants, S3, M3D3), linear quadrilaterals (CPE4, CPE4R,
  CPE4I, CPS4, CPEG4, ... S4, M3D4) and 2-node lines (T2D2, B21, R2D2);
* ``*NSET`` and ``*ELSET`` (ids, names of other sets, or ``GENERATE`` triples);
* ``*SURFACE, TYPE=ELEMENT`` (lines ``element-or-elset, S1..S4``, or an elset alone for all
  its free faces) and ``*SURFACE, TYPE=NODE``;
* ``*INCLUDE, INPUT=...``; ``*PART`` / ``*INSTANCE`` with one instance (a translation line
  is applied, a rotation refused).

Everything else (materials, steps, loads) is skipped. Face ``Sk`` of an element joins its
nodes k and k + 1 (the last face closes the loop), the Abaqus convention for 2D solids.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from .sets import RawMesh

TRIANGLES = {"CPE3", "CPE3H", "CPS3", "CPEG3", "CPEG3H", "S3", "S3R", "STRI3", "M3D3"}
QUADS = {"CPE4", "CPE4H", "CPE4I", "CPE4IH", "CPE4R", "CPE4RH", "CPS4", "CPS4I", "CPS4R",
         "CPEG4", "CPEG4H", "CPEG4I", "CPEG4IH", "CPEG4R", "CPEG4RH", "S4", "S4R", "M3D4",
         "M3D4R"}
LINES = {"T2D2", "T2D2H", "B21", "B21H", "R2D2", "RB2D2"}
KINDS = {**{t: ("triangle", 3) for t in TRIANGLES}, **{t: ("quad", 4) for t in QUADS},
         **{t: ("line", 2) for t in LINES}}


def _keyword(line: str):
    """(KEYWORD, {PARAM: value or None}) of a keyword line."""
    parts = [p.strip() for p in line[1:].split(",")]
    params = {}
    for p in parts[1:]:
        if not p:
            continue
        key, _, value = p.partition("=")
        params[key.strip().upper()] = value.strip() if value else None
    return parts[0].upper(), params


def _lines(path: Path, depth=0):
    """(file, line number, text) of every non-comment line, includes expanded."""
    if depth > 10:
        raise InputError(f"{path}: *INCLUDE nested more than 10 deep")
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    for number, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s or s.startswith("**"):
            continue
        if s.startswith("*") and s[1:].split(",")[0].strip().upper() == "INCLUDE":
            _, params = _keyword(s)
            name = params.get("INPUT")
            if not name:
                raise InputError(f"{path}:{number}: *INCLUDE needs INPUT=file")
            target = Path(name.strip('"'))
            if not target.is_absolute():
                target = path.parent / target
            if not target.is_file():
                raise InputError(f"{path}:{number}: included file {name!r} not found")
            yield from _lines(target, depth + 1)
            continue
        yield path, number, s


def _blocks(path: Path):
    """(keyword, params, where, data lines [(where, text)]) of each keyword block."""
    current = None
    for file, number, s in _lines(path):
        where = f"{file}:{number}"
        if s.startswith("*"):
            if current is not None:
                yield current
            keyword, params = _keyword(s)
            current = (keyword, params, where, [])
        elif current is not None:
            current[3].append((where, s))
    if current is not None:
        yield current


def _fields(where, text):
    return [f.strip() for f in text.rstrip(",").split(",")]


def _ints(where, fields):
    try:
        return [int(f) for f in fields if f]
    except ValueError:
        raise InputError(f"{where}: expected integers, got {', '.join(fields)!r}") from None


def read_inp(path) -> RawMesh:
    """Read the mesh and named sets of an Abaqus input file (see the module docstring)."""
    path = Path(path)
    node_ids, coords = [], []
    elements = []          # (kind, connectivity ids, element ids, where)
    node_sets, element_sets, surfaces = {}, {}, {}
    instances = 0
    translation = None
    for keyword, params, where, data in _blocks(path):
        if keyword == "NODE":
            ids = []
            for w, text in data:
                f = _fields(w, text)
                try:
                    ids.append(int(f[0]))
                    xyz = [float(v) for v in f[1:4] if v]
                except (ValueError, IndexError):
                    raise InputError(f"{w}: expected 'id, x, y[, z]', got {text!r}") from None
                if len(xyz) < 2:
                    raise InputError(f"{w}: a node needs at least x and y, got {text!r}")
                coords.append(xyz + [0.0] * (3 - len(xyz)))
            node_ids += ids
            if params.get("NSET"):
                node_sets.setdefault(params["NSET"], []).append(("ids", ids, where))
        elif keyword == "ELEMENT":
            etype = (params.get("TYPE") or "").upper()
            if etype not in KINDS:
                why = ("quadratic elements are not supported"
                       if etype[-1:] in "5678" or etype.endswith(("8R", "6M", "6H"))
                       else "axisymmetric elements: impactfv solves plane strain"
                       if etype.startswith("CAX") else "not a supported element type")
                raise InputError(f"{where}: *ELEMENT TYPE={etype or '?'}: {why} (linear "
                                 "triangles CPE3/CPS3, quadrilaterals CPE4/CPE4R/CPS4 and "
                                 "2-node lines T2D2 are)")
            kind, k = KINDS[etype]
            values = []
            for w, text in data:
                values += _ints(w, _fields(w, text))
            if len(values) % (k + 1):
                raise InputError(f"{where}: *ELEMENT TYPE={etype}: expected 'id' and {k} "
                                 "node ids per element")
            table = np.array(values, dtype=np.int64).reshape(-1, k + 1)
            elements.append((kind, table[:, 1:], table[:, 0], where))
            if params.get("ELSET"):
                element_sets.setdefault(params["ELSET"], []).append(
                    ("ids", table[:, 0].tolist(), where))
        elif keyword in ("NSET", "ELSET"):
            name = params.get(keyword)
            if not name:
                raise InputError(f"{where}: *{keyword} needs {keyword}=name")
            target = node_sets if keyword == "NSET" else element_sets
            target.setdefault(name, []).extend(_set_items(where, data, "GENERATE" in params))
        elif keyword == "SURFACE":
            name = params.get("NAME")
            if not name:
                raise InputError(f"{where}: *SURFACE needs NAME=name")
            kind = (params.get("TYPE") or "ELEMENT").upper()
            if kind not in ("ELEMENT", "NODE"):
                raise InputError(f"{where}: *SURFACE TYPE={kind} is not supported (ELEMENT "
                                 "or NODE)")
            items = []
            for w, text in data:
                f = _fields(w, text)
                items.append((w, f[0], f[1].upper() if len(f) > 1 and f[1] else None))
            surfaces[name] = (kind, items, where)
        elif keyword == "INSTANCE":
            instances += 1
            if instances > 1:
                raise InputError(f"{where}: a second *INSTANCE: give one body (one part, one "
                                 "instance) per .inp file")
            numbers = [[float(v) for v in _fields(w, t)] for w, t in data]
            if len(numbers) > 1 and any(abs(v) > 0 for v in numbers[1][6:7]):
                raise InputError(f"{where}: *INSTANCE with a rotation is not supported "
                                 "(export the mesh in assembly coordinates)")
            if numbers:
                translation = (numbers[0] + [0.0, 0.0, 0.0])[:3]
    if not node_ids:
        raise InputError(f"{path}: no *NODE found")
    points = np.array(coords, dtype=float)
    if translation is not None:
        points = points + np.array(translation)
    index = {nid: i for i, nid in enumerate(node_ids)}
    if len(index) != len(node_ids):
        raise InputError(f"{path}: node ids are not unique (several parts? give one body per "
                         "file)")
    raw = RawMesh(points)
    element_number = {}
    offset = 0
    for kind, conn, ids, where in elements:
        try:
            local = np.vectorize(index.__getitem__, otypes=[np.int64])(conn) if conn.size \
                else conn
        except KeyError as exc:
            raise InputError(f"{where}: element refers to node {exc.args[0]}, which no *NODE "
                             "defines") from None
        raw.blocks.append((kind, local.reshape(conn.shape)))
        for j, eid in enumerate(ids.tolist()):
            if eid in element_number:
                raise InputError(f"{where}: element id {eid} is defined twice")
            element_number[eid] = offset + j
        offset += len(ids)
    sizes = [len(b[1]) for b in raw.blocks]
    kinds = np.repeat([b[0] for b in raw.blocks], sizes) if raw.blocks else np.array([])
    resolved_nodes, resolved_elements = {}, {}

    def resolve(name, sets, lookup, cache, what, stack=()):
        if name in cache:
            return cache[name]
        if name not in sets or name in stack:
            return None
        out = []
        for item in sets[name]:
            tag, values, w = item
            if tag == "ids":
                for v in values:
                    if v not in lookup:
                        raise InputError(f"{w}: {what} set {name!r} names {what} {v}, which "
                                         "the file does not define")
                    out.append(lookup[v])
            else:
                sub = resolve(values, sets, lookup, cache, what, stack + (name,))
                if sub is None:
                    raise InputError(f"{w}: {what} set {name!r} names an unknown set "
                                     f"{values!r}")
                out += sub.tolist()
        cache[name] = np.unique(np.array(out, dtype=np.int64))
        return cache[name]

    for name in node_sets:
        raw.node_sets[name] = resolve(name, node_sets, index, resolved_nodes, "node")
    for name in element_sets:
        raw.element_sets[name] = resolve(name, element_sets, element_number,
                                         resolved_elements, "element")
    for name, (kind, items, where) in surfaces.items():
        if kind == "NODE":
            nodes = []
            for w, ref, _ in items:
                if ref.lstrip("-").isdigit():
                    if int(ref) not in index:
                        raise InputError(f"{w}: surface {name!r} names node {ref}, which the "
                                         "file does not define")
                    nodes.append(index[int(ref)])
                elif ref in raw.node_sets:
                    nodes += raw.node_sets[ref].tolist()
                else:
                    raise InputError(f"{w}: surface {name!r} names an unknown node set "
                                     f"{ref!r}")
            raw.node_sets[name] = np.unique(np.array(nodes, dtype=np.int64))
            continue
        faces, whole = [], []
        for w, ref, face in items:
            if ref.lstrip("-").isdigit():
                if int(ref) not in element_number:
                    raise InputError(f"{w}: surface {name!r} names element {ref}, which the "
                                     "file does not define")
                numbers = np.array([element_number[int(ref)]])
            elif ref in raw.element_sets:
                numbers = raw.element_sets[ref]
            else:
                raise InputError(f"{w}: surface {name!r} names an unknown element set "
                                 f"{ref!r}")
            if face is None:
                whole += numbers.tolist()
                continue
            if not (face.startswith("S") and face[1:].isdigit()):
                raise InputError(f"{w}: surface {name!r}: face {face!r} is not supported "
                                 "(S1, S2, S3 of triangles, S1..S4 of quadrilaterals)")
            k = int(face[1:]) - 1
            for e in numbers.tolist():
                n_faces = {"triangle": 3, "quad": 4}.get(kinds[e], 0)
                if not 0 <= k < n_faces:
                    raise InputError(f"{w}: surface {name!r}: element {kinds[e]} has no "
                                     f"face {face}")
                faces.append((e, k))
        raw.face_sets[name] = np.array(faces, dtype=np.int64).reshape(-1, 2)
        if whole:
            # an element set without a face id: all the free faces of its elements
            raw.surface_elements[name] = np.unique(np.array(whole, dtype=np.int64))
    return raw


def _set_items(where, data, generate):
    items = []
    for w, text in data:
        f = _fields(w, text)
        if generate:
            values = _ints(w, f)
            if len(values) not in (2, 3):
                raise InputError(f"{w}: GENERATE expects 'first, last[, step]'")
            first, last, step = (values + [1])[:3]
            if step <= 0 or last < first:
                raise InputError(f"{w}: GENERATE expects first <= last and a positive step")
            items.append(("ids", list(range(first, last + 1, step)), w))
            continue
        for v in f:
            if not v:
                continue
            if v.lstrip("-").isdigit():
                items.append(("ids", [int(v)], w))
            else:
                items.append(("set", v, w))
    return items
