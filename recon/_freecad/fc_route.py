# Runs inside freecadcmd: the mesh → B-rep route FreeCAD users take today (Part workbench "Shape from mesh",
# "Refine shape", "Convert to solid", export STEP), timed per stage.
import json
import os
import time

import Mesh
import Part

stages = {}
t = time.perf_counter()
mesh = Mesh.Mesh(os.environ["RECON_FC_MESH"])
stages["load"] = time.perf_counter() - t

t = time.perf_counter()
shape = Part.Shape()
# mesh-to-shape sewing tolerance in model units: FreeCAD's own default for makeShapeFromMesh (its route, not recon's)
shape.makeShapeFromMesh(mesh.Topology, 0.01)
stages["shape_from_mesh"] = time.perf_counter() - t

t = time.perf_counter()
refined = shape.removeSplitter()
stages["refine"] = time.perf_counter() - t

t = time.perf_counter()
try:
    solid = Part.makeSolid(Part.Shell(refined.Faces))
except Exception:  # an open or non-manifold mesh: FreeCAD users end up with the shell
    solid = refined
stages["solid"] = time.perf_counter() - t

t = time.perf_counter()
solid.exportStep(os.environ["RECON_FC_STEP"])
stages["export"] = time.perf_counter() - t

with open(os.environ["RECON_FC_OUT"], "w") as fh:
    json.dump(
        {
            "faces": len(solid.Faces),
            "valid": bool(solid.isValid()),
            "type": solid.ShapeType,
            "seconds": sum(stages.values()),
            "stages": stages,
            "step_bytes": os.path.getsize(os.environ["RECON_FC_STEP"]),
        },
        fh,
    )
