"""Builds an animated camera in Blender, exports it with Blender's own glTF exporter and writes
Blender's own evaluated camera per frame to JSON: the fixtures of tests/gltf_camera.rs's
`a_blender_export_gives_blenders_camera` (tests/fixtures/blender_camera/). Not part of .ci/run
(Blender is not installed there; the test reads only the committed files); run by hand, with
Debian's blender 3.4 (`apt-get install -y blender`):

    blender -b --factory-startup --python tests/blender_camera.py -- tests/fixtures/blender_camera

The camera "ShotCam" is the child of an empty "Rig"; 24 fps, frames 1-24, render 1200x800
(aspect 3:2), a 30 mm lens on a 36 mm sensor (sensor fit AUTO: the 36 mm span the wider,
horizontal side), clip 0.1-150 m. Keyframed (Blender's default Bezier curves): the rig's
location, Z rotation and uniform scale (1 -> 1.6), the camera's location and XYZ Euler
rotation, at frames 1, 9, 17 and 24. The exporter samples every frame (glTF LINEAR keys) into one
animation (export_nla_strips=False), with +Y up.

Written per frame, after scene.frame_set(frame), all of it Blender's own numbers in its Z-up
world: the camera's matrix_world (the rig's scale included), the projection matrix of
Object.calc_matrix_camera at the render size (OpenGL clip space, depth -1..1), the data's
angle_y, lens, sensor_width, clip_start, clip_end. Converting them to glTF's Y-up world and to
snell's time is the test's job (it says how).
"""
import bpy
import json
import math
import os
import sys

out = sys.argv[sys.argv.index('--') + 1]
os.makedirs(out, exist_ok=True)

for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj, do_unlink=True)

scene = bpy.context.scene
scene.render.fps = 24
scene.render.fps_base = 1.0
scene.frame_start = 1
scene.frame_end = 24
scene.render.resolution_x = 1200
scene.render.resolution_y = 800
scene.render.resolution_percentage = 100
scene.render.pixel_aspect_x = 1.0
scene.render.pixel_aspect_y = 1.0

rig = bpy.data.objects.new("Rig", None)
scene.collection.objects.link(rig)
data = bpy.data.cameras.new("ShotCamData")
data.type = 'PERSP'
data.lens = 30.0
data.sensor_width = 36.0
data.sensor_fit = 'AUTO'
data.clip_start = 0.1
data.clip_end = 150.0
cam = bpy.data.objects.new("ShotCam", data)
scene.collection.objects.link(cam)
cam.parent = rig
scene.camera = cam

# (frame, rig location, rig z rotation deg, rig scale, camera location, camera euler deg)
KEYS = [
    (1, (0.0, -1.0, 0.6), 0.0, 1.0, (0.2, -1.5, 0.9), (70.0, 0.0, 5.0)),
    (9, (0.3, -0.8, 0.7), 12.0, 1.2, (0.1, -1.4, 1.0), (62.0, 4.0, 10.0)),
    (17, (0.6, -0.5, 0.8), 25.0, 1.45, (-0.1, -1.3, 1.1), (58.0, -3.0, 18.0)),
    (24, (0.8, -0.2, 0.9), 35.0, 1.6, (-0.2, -1.2, 1.2), (55.0, 2.0, 24.0)),
]
for frame, rig_loc, rig_rz, rig_s, cam_loc, cam_rot in KEYS:
    rig.location = rig_loc
    rig.rotation_euler = (0.0, 0.0, math.radians(rig_rz))
    rig.scale = (rig_s, rig_s, rig_s)
    for path in ("location", "rotation_euler", "scale"):
        rig.keyframe_insert(data_path=path, frame=frame)
    cam.location = cam_loc
    cam.rotation_euler = tuple(math.radians(a) for a in cam_rot)
    for path in ("location", "rotation_euler"):
        cam.keyframe_insert(data_path=path, frame=frame)

gltf_path = os.path.join(out, "blender_shot.gltf")
bpy.ops.export_scene.gltf(
    filepath=gltf_path,
    export_format='GLTF_SEPARATE',
    export_cameras=True,
    export_animations=True,
    export_force_sampling=True,
    export_frame_range=True,
    export_nla_strips=False,
    export_yup=True,
    export_apply=False,
)

depsgraph = bpy.context.evaluated_depsgraph_get()
frames = []
for frame in range(scene.frame_start, scene.frame_end + 1):
    scene.frame_set(frame)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = cam.evaluated_get(depsgraph)
    projection = evaluated.calc_matrix_camera(
        depsgraph,
        x=scene.render.resolution_x,
        y=scene.render.resolution_y,
        scale_x=scene.render.pixel_aspect_x,
        scale_y=scene.render.pixel_aspect_y,
    )
    frames.append({
        "frame": frame,
        "matrix_world": [list(row) for row in evaluated.matrix_world],
        "projection": [list(row) for row in projection],
        "angle_y": evaluated.data.angle_y,
        "lens": evaluated.data.lens,
        "sensor_width": evaluated.data.sensor_width,
        "clip_start": evaluated.data.clip_start,
        "clip_end": evaluated.data.clip_end,
    })

with open(os.path.join(out, "blender_camera.json"), "w") as f:
    json.dump({
        "blender": bpy.app.version_string,
        "fps": scene.render.fps / scene.render.fps_base,
        "resolution": [scene.render.resolution_x, scene.render.resolution_y],
        "matrices": "rows (matrix[row][column]); Blender's Z-up world",
        "frames": frames,
    }, f, indent=1)
print("WROTE", gltf_path)
