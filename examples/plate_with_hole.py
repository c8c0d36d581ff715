"""Mesh a plate with a hole with gmsh, for examples/plate_with_hole.toml.

    pip install "impactfv[gmsh]"
    python examples/plate_with_hole.py        # writes examples/plate_with_hole.msh

The plate is 20 mm x 10 mm with a hole of radius 2.5 mm in its middle; coordinates are in
millimetres (the case reads the mesh with scale = 1e-3). Physical groups name what the case
refers to: the curves "clamp" (x = 0), "struck" (x = 20 mm), "sides" (y = 0 and y = 10 mm)
and "hole" become boundary regions; the surface group "plate" holds the triangles (gmsh
writes only the elements of physical groups once any group is defined).
"""

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def make_mesh(path=HERE / "plate_with_hole.msh", size=0.6):
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("plate_with_hole")
        occ = gmsh.model.occ
        plate = occ.addRectangle(0.0, 0.0, 0.0, 20.0, 10.0)
        hole = occ.addDisk(10.0, 5.0, 0.0, 2.5, 2.5)
        (surface,), _ = occ.cut([(2, plate)], [(2, hole)])
        occ.synchronize()
        groups = {"clamp": [], "struck": [], "sides": [], "hole": []}
        for dim, tag in gmsh.model.getBoundary([surface], oriented=False):
            x, y, _ = occ.getCenterOfMass(dim, tag)
            name = ("clamp" if abs(x) < 1e-9 else "struck" if abs(x - 20.0) < 1e-9
                    else "sides" if abs(y) < 1e-9 or abs(y - 10.0) < 1e-9 else "hole")
            groups[name].append(tag)
        for name, tags in groups.items():
            gmsh.model.addPhysicalGroup(1, tags, name=name)
        gmsh.model.addPhysicalGroup(2, [surface[1]], name="plate")
        gmsh.option.setNumber("Mesh.MeshSizeMin", size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.Algorithm", 6)        # Frontal-Delaunay
        gmsh.model.mesh.generate(2)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return Path(path)


if __name__ == "__main__":
    print(make_mesh(*sys.argv[1:2]))
