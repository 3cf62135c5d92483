"""Run inside Blender: import a glTF and report what Blender made of it, as JSON.

    blender --background --factory-startup --python tools/blender_import_check.py -- FILE.glb REPORT.json
"""

import json
import sys

import bpy
import numpy

# Debian's Blender 3.4 glTF importer still says np.bool, which numpy 1.24 (Debian's) removed; give the
# alias back so the importer runs (fixed upstream in Blender 3.5's importer).
if not hasattr(numpy, "bool"):
    numpy.bool = bool

glb, report = sys.argv[sys.argv.index("--") + 1:][:2]
for obj in list(bpy.data.objects):  # the factory scene's cube, camera and light
    bpy.data.objects.remove(obj)
bpy.ops.import_scene.gltf(filepath=glb)
meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
found = {"meshes": len(meshes), "objects": []}
for obj in meshes:
    keys = obj.data.shape_keys
    action = keys.animation_data.action if keys is not None and keys.animation_data else None
    found["objects"].append({
        "name": obj.name,
        "vertices": len(obj.data.vertices),
        "shape_keys": [k.name for k in keys.key_blocks] if keys is not None else [],
        "animated_keys": len(action.fcurves) if action else 0,
        "frame_range": list(action.frame_range) if action else None,
        "textured": any(n.type == "TEX_IMAGE" for m in obj.data.materials if m and m.use_nodes
                        for n in m.node_tree.nodes),
    })
with open(report, "w") as handle:
    json.dump(found, handle)
