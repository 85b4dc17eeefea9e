"""Reads a USD stage with Pixar's USD library (PyPI usd-core) and reports what a pipeline sees.

Usage: read_stage.py STAGE OUT_DIR

Prints one JSON object: the stage metadata (upAxis, metersPerUnit, timeCodesPerSecond,
framesPerSecond, startTimeCode, endTimeCode, defaultPrim) and, for every UsdGeomMesh, its
topology, UVs, subdivision scheme, the time codes of its `points` samples and the `extent`
at each of them. The points themselves go to OUT_DIR/<mesh>.f32: every sample in time order,
x y z little-endian float32 per point, so the caller can compare them bit for bit.
Exits 1 when the stage does not open.
"""

import array
import json
import os
import sys

from pxr import Usd, UsdGeom


def floats(values):
    """Flattens Gf vectors into Python floats (exact: float32 widened to double)."""
    return [float(c) for v in values for c in v]


def main():
    stage_path, out_dir = sys.argv[1], sys.argv[2]
    stage = Usd.Stage.Open(stage_path)
    if stage is None:
        print(json.dumps({"error": "cannot open " + stage_path}))
        return 1
    root = stage.GetRootLayer()
    report = {
        "upAxis": str(UsdGeom.GetStageUpAxis(stage)),
        "metersPerUnit": UsdGeom.GetStageMetersPerUnit(stage),
        "timeCodesPerSecond": stage.GetTimeCodesPerSecond(),
        "framesPerSecond": stage.GetFramesPerSecond(),
        "startTimeCode": stage.GetStartTimeCode(),
        "endTimeCode": stage.GetEndTimeCode(),
        "defaultPrim": root.defaultPrim,
        "meshes": {},
    }
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        mesh = UsdGeom.Mesh(prim)
        points_attr = mesh.GetPointsAttr()
        times = points_attr.GetTimeSamples()
        name = prim.GetName()
        data = array.array("f")
        extents = []
        counts = set()
        for t in times:
            pts = points_attr.Get(t)
            counts.add(len(pts))
            data.extend(floats(pts))
            extents.append(floats(mesh.GetExtentAttr().Get(t)))
        if sys.byteorder != "little":
            data.byteswap()
        with open(os.path.join(out_dir, name + ".f32"), "wb") as f:
            data.tofile(f)
        st = UsdGeom.PrimvarsAPI(prim).GetPrimvar("st")
        report["meshes"][name] = {
            "path": str(prim.GetPath()),
            "times": list(times),
            "pointCounts": sorted(counts),
            "extents": extents,
            "faceVertexCounts": list(mesh.GetFaceVertexCountsAttr().Get()),
            "faceVertexIndices": list(mesh.GetFaceVertexIndicesAttr().Get()),
            "subdivisionScheme": str(mesh.GetSubdivisionSchemeAttr().Get()),
            "doubleSided": bool(mesh.GetDoubleSidedAttr().Get()),
            "st": floats(st.Get()) if st and st.HasValue() else None,
            "stInterpolation": str(st.GetInterpolation()) if st else None,
        }
    print(json.dumps(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
