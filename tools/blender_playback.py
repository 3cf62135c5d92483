"""Run inside Blender: import a glTF, play its animation at given times and save what Blender shows.

    blender --background --factory-startup --python tools/blender_playback.py -- FILE.glb TIMES.json OUT.npz

For each time ``t`` (seconds) the scene is set to frame ``t * fps / fps_base`` (the importer keys a glTF
animation at ``time * scene fps``, on the scene's own 24 fps, from frame 0), with the fraction as a
subframe, and the evaluated mesh (shape keys applied) is read, in world space and Blender's axes (+Z up).
``OUT.npz`` holds ``positions (len(times), N, 3)`` and ``report``, a JSON string: the scene's fps and frame
range, the shape keys with their slider ranges, the action's frame range, the vertex count.
"""

import json
import math
import sys

import bpy
import numpy

# Debian's Blender 3.4 glTF importer still says np.bool, which numpy 1.24 (Debian's) removed; give the
# alias back so the importer runs (fixed upstream in Blender 3.5's importer).
if not hasattr(numpy, "bool"):
    numpy.bool = bool

glb, times_path, out = sys.argv[sys.argv.index("--") + 1:][:3]
with open(times_path) as handle:
    times = json.load(handle)
for obj in list(bpy.data.objects):  # the factory scene's cube, camera and light
    bpy.data.objects.remove(obj)
bpy.ops.import_scene.gltf(filepath=glb)
scene = bpy.context.scene
(obj,) = [o for o in scene.objects if o.type == "MESH"]
keys = obj.data.shape_keys
action = keys.animation_data.action if keys is not None and keys.animation_data else None
fps = scene.render.fps / scene.render.fps_base
world = numpy.array(obj.matrix_world)
positions = []
for t in times:
    frame = t * fps
    whole = math.floor(frame)
    scene.frame_set(whole, subframe=frame - whole)
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    co = numpy.empty(3 * len(mesh.vertices))
    mesh.vertices.foreach_get("co", co)
    evaluated.to_mesh_clear()
    co = co.reshape(-1, 3)
    positions.append(co @ world[:3, :3].T + world[:3, 3])
report = {
    "fps": fps,
    "frame_start": scene.frame_start,
    "frame_end": scene.frame_end,
    "vertices": len(obj.data.vertices),
    "keys": {k.name: [k.slider_min, k.slider_max] for k in keys.key_blocks[1:]} if keys is not None else {},
    "animated_keys": len(action.fcurves) if action else 0,
    "action_frame_range": list(action.frame_range) if action else None,
}
numpy.savez(out, positions=numpy.array(positions), report=json.dumps(report))
