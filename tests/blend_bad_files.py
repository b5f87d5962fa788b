"""Purpose-built .blend files that each trip one check of the .blend corpus import.

``MAKE_FILES`` runs in the Blender worker environment's Python (``python script.py FOLDER``)
and writes every file into FOLDER: small armatures (a ``root`` control bone, an ``arm``
control bone under it, a deform bone ``DEF-arm`` following it), keyed as a user would.
"""

MAKE_FILES = r"""
import sys
import bpy

folder = sys.argv[1]


def reset():
    bpy.ops.wm.read_factory_settings(use_empty=True)


def armature(name="Rig"):
    data = bpy.data.armatures.new(name + "Data")
    obj = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    root = data.edit_bones.new("root")
    root.head, root.tail = (0, 0, 0), (0, 0, 1)
    arm = data.edit_bones.new("arm")
    arm.head, arm.tail, arm.parent = (0, 0, 1), (1, 0, 1), root
    deform = data.edit_bones.new("DEF-arm")
    deform.head, deform.tail, deform.parent = (0, 0, 1), (1, 0, 1), arm
    bpy.ops.object.mode_set(mode="OBJECT")
    for bone in obj.data.bones:
        bone.use_deform = bone.name.startswith("DEF-")
    for bone in obj.pose.bones:
        bone.rotation_mode = "XYZ"
    obj.pose.bones["root"]["switch"] = 0.0
    obj.pose.bones["root"].id_properties_ui("switch").update(min=0.0, max=1.0)
    return obj


def key(obj, action_name, path, index, frames_values):
    action = bpy.data.actions.get(action_name) or bpy.data.actions.new(action_name)
    action.use_fake_user = True
    animation = obj.animation_data_create()
    animation.action = action
    fcurve = action.fcurve_ensure_for_datablock(obj, path, index=index)
    for frame, value in frames_values:
        fcurve.keyframe_points.insert(frame, value)
    return action


def save(name):
    bpy.ops.wm.save_as_mainfile(filepath=f"{folder}/{name}.blend")


SWING = [(1, 0.0), (10, 0.8), (20, -0.3)]

reset()  # a mesh, no armature
mesh = bpy.data.objects.new("Skin", bpy.data.meshes.new("SkinMesh"))
bpy.context.scene.collection.objects.link(mesh)
save("no_armature")

reset()  # two armatures, neither chosen
for name in ("Hero", "Sidekick"):
    key(armature(name), f"{name}Walk", 'pose.bones["arm"].rotation_euler', 2, SWING)
save("two_armatures")

reset()  # an armature and no action
armature()
save("no_actions")

reset()  # one action on the control, one on the deform bone only
rig = armature()
key(rig, "Swing", 'pose.bones["arm"].rotation_euler', 2, SWING)
key(rig, "Skinned", 'pose.bones["DEF-arm"].rotation_euler', 2, SWING)
save("deform_only")

reset()  # the switch keyed once in each action
rig = armature()
key(rig, "Swing", 'pose.bones["arm"].rotation_euler', 2, SWING)
key(rig, "Swing", 'pose.bones["root"]["switch"]', 0, [(5, 1.0)])
key(rig, "Lift", 'pose.bones["arm"].rotation_euler', 0, SWING)
key(rig, "Lift", 'pose.bones["root"]["switch"]', 0, [(1, 1.0)])
save("one_frame")

reset()  # a driver reading the frame, a constraint following an animated empty
rig = armature()
key(rig, "Swing", 'pose.bones["arm"].rotation_euler', 2, SWING)
key(rig, "Lift", 'pose.bones["arm"].rotation_euler', 0, SWING)
driver = rig.driver_add('pose.bones["arm"].scale', 1).driver
driver.type, driver.expression = "SCRIPTED", "1 + frame / 100"
empty = bpy.data.objects.new("Target", None)
bpy.context.scene.collection.objects.link(empty)
key(empty, "TargetMove", "location", 0, [(1, 0.0), (20, 2.0)])
constraint = rig.pose.bones["root"].constraints.new("COPY_LOCATION")
constraint.target = empty
save("frame_dependent")

reset()  # a Python driver drawing a random number at each evaluation
rig = armature()
key(rig, "Swing", 'pose.bones["arm"].rotation_euler', 2, SWING)
key(rig, "Lift", 'pose.bones["arm"].rotation_euler', 0, SWING)
driver = rig.driver_add('pose.bones["arm"].location', 1).driver
driver.type, driver.expression = "SCRIPTED", "__import__('random').random()"
save("random_driver")

reset()  # good, but with curves rigmap's keys cannot carry: they are baked
rig = armature()
ease = key(rig, "Ease", 'pose.bones["arm"].rotation_euler', 2, SWING)
for point in ease.layers[0].strips[0].channelbag(ease.slots[0]).fcurves[0].keyframe_points:
    point.interpolation, point.easing = "SINE", "EASE_IN_OUT"
key(rig, "Ease", 'pose.bones["arm"].location', 0, [(1, 0.0), (8, 0.25), (20, 0.1)])
rig.pose.bones["root"].rotation_mode = "QUATERNION"
for index, values in enumerate([(1.0, 0.7071), (0.0, 0.0), (0.0, 0.0), (0.0, 0.7071)]):
    path = 'pose.bones["root"].rotation_quaternion'
    key(rig, "Quat", path, index, [(1, values[0]), (20, values[1])])
cycle = key(rig, "Cycle", 'pose.bones["arm"].rotation_euler', 0, [(1, 0.0), (5, 0.5), (10, 0.0)])
cycle.layers[0].strips[0].channelbag(cycle.slots[0]).fcurves[0].modifiers.new("CYCLES")
cycle.use_frame_range, cycle.frame_start, cycle.frame_end = True, 1, 30
save("bakes")
"""
