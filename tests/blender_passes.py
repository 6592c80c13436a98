"""Lists what Blender shows of an EXR frame: the passes of a compositor Image node and the
Cryptomatte layer its Cryptomatte node finds. Not part of .ci/run (Blender is not installed
there); run by hand:

    blender -b --factory-startup --python tests/blender_passes.py -- output/pool/pool.0024.exr

Blender prints "multilayer read: unknown channel token: ..." for each channel it drops.
"""
import bpy, sys
path = sys.argv[sys.argv.index('--') + 1]
img = bpy.data.images.load(path)
scene = bpy.context.scene
scene.use_nodes = True
tree = scene.node_tree
node = tree.nodes.new('CompositorNodeImage')
node.image = img
print("IMAGE TYPE", img.type)
print("LAYER", repr(node.layer))
for o in node.outputs:
    print("PASS", o.name, o.type, o.enabled)
crypto = tree.nodes.new('CompositorNodeCryptomatteV2')
crypto.source = 'IMAGE'
crypto.image = img
try:
    print("CRYPTO LAYER", repr(crypto.layer_name))
except Exception as e:
    print("CRYPTO ERR", e)
