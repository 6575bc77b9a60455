# Runs inside freecadcmd (FreeCAD's own Python). Arguments come in the environment.
import json
import os
import time

import FreeCAD
import Import

t0 = time.perf_counter()
doc = FreeCAD.newDocument("recon_check")
Import.insert(os.environ["RECON_FC_STEP"], doc.Name)
objects, names = [], []
for obj in doc.Objects:
    shape = getattr(obj, "Shape", None)
    if shape is None or shape.isNull():
        continue
    if shape.ShapeType == "Face":
        names.append(obj.Label)
        continue
    objects.append(
        {
            "label": obj.Label,
            "type": shape.ShapeType,
            "valid": bool(shape.isValid()),
            "volume": float(shape.Volume),
            "faces": len(shape.Faces),
            "solids": len(shape.Solids),
            "closed": all(s.isClosed() for s in shape.Shells) if shape.Shells else False,
        }
    )
with open(os.environ["RECON_FC_OUT"], "w") as fh:
    json.dump({"objects": objects, "face_names": names, "seconds": time.perf_counter() - t0}, fh)
