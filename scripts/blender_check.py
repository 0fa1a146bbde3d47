# Manual check that a point cache written by hmc plays back in Blender as
# intended (docs/blender.md). Not part of CI: Blender is not on CI machines.
#
#   blender -b --factory-startup --python scripts/blender_check.py -- \
#       NEUTRAL.obj SEQ.pc2 FRAME EXPECTED.obj
#
# Imports NEUTRAL.obj with the axis settings of docs/blender.md (vertex order
# kept), adds a Mesh Cache modifier reading SEQ (.pc2 or .mdd) with the same
# axis settings, evaluates scene frame FRAME and compares the evaluated
# vertices with EXPECTED.obj imported the same way. Prints the largest
# difference; exits 0 on a match within float32 rounding, 1 on a mismatch,
# 2 on an error.
import math
import os
import struct
import sys
import traceback

import addon_utils
import bpy

# The settings docs/blender.md documents. hmc files are +Y up, millimetres;
# Blender is +Z up. The OBJ importer (Forward -Z, Up Y: its defaults) keeps
# the file's coordinates in the mesh and puts the Y-up -> Z-up rotation on
# the object (matrix_world). The Mesh Cache modifier writes the cache into
# that same local space, so its own axis conversion must stay the identity
# (Forward +Y, Up +Z: its defaults).
OBJ_AXIS_FORWARD = "-Z"
OBJ_AXIS_UP = "Y"
CACHE_FORWARD = "POS_Y"
CACHE_UP = "POS_Z"


def cache_header(path):
    """(points, frames, start frame) from a .pc2 or .mdd header."""
    with open(path, "rb") as f:
        data = f.read(64)
    if path.lower().endswith(".pc2"):
        magic, _version, points, start, rate, samples = struct.unpack(
            "<12siiffi", data[:32])
        if magic != b"POINTCACHE2\0" or rate != 1.0:
            raise ValueError(f"{path}: not a one-sample-per-frame PC2 file")
        return points, samples, int(round(start))
    frames, points = struct.unpack(">ii", data[:8])
    # hmc writes time = frame / fps: the first frame number is t0 / spacing.
    with open(path, "rb") as f:
        f.seek(8)
        times = struct.unpack(f">{min(frames, 2)}f", f.read(4 * min(frames, 2)))
    if frames < 2:
        raise ValueError(f"{path}: need two frames to number MDD frames")
    return points, frames, int(round(times[0] / (times[1] - times[0])))


def import_obj(path):
    """Imports an OBJ keeping its vertex order; returns the new object."""
    before = set(bpy.data.objects)
    bpy.ops.import_scene.obj(
        filepath=path,
        split_mode="OFF",           # "Keep Vert Order": no split, no reorder
        use_split_objects=False,
        use_split_groups=False,
        use_groups_as_vgroups=False,
        use_edges=True,
        use_smooth_groups=False,
        use_image_search=False,
        global_clamp_size=0.0,
        axis_forward=OBJ_AXIS_FORWARD,
        axis_up=OBJ_AXIS_UP)
    new = [o for o in bpy.data.objects if o not in before]
    if len(new) != 1:
        raise RuntimeError(f"{path}: import made {len(new)} objects, not 1")
    return new[0]


def local_coords(obj, evaluated):
    if evaluated:
        depsgraph = bpy.context.evaluated_depsgraph_get()
        eval_obj = obj.evaluated_get(depsgraph)
        mesh = eval_obj.to_mesh()
        coords = [tuple(v.co) for v in mesh.vertices]
        eval_obj.to_mesh_clear()
        return coords
    return [tuple(v.co) for v in obj.data.vertices]


def max_difference(a, b):
    return max(abs(p - q) for u, v in zip(a, b) for p, q in zip(u, v))


def main(argv):
    if len(argv) != 4:
        print(__doc__ if __doc__ else "usage: NEUTRAL.obj SEQ.pc2 FRAME "
              "EXPECTED.obj")
        return 2
    neutral_path, cache_path, frame, expected_path = argv
    frame = int(frame)
    points, frames, start = cache_header(cache_path)
    print(f"cache: {cache_path}: {points} points, {frames} frames "
          f"{start}..{start + frames - 1}")

    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon_utils.enable("io_scene_obj", default_set=True)
    neutral = import_obj(os.path.abspath(neutral_path))
    if len(neutral.data.vertices) != points:
        print(f"MISMATCH: {neutral_path} has {len(neutral.data.vertices)} "
              f"vertices, the cache {points}")
        return 1

    modifier = neutral.modifiers.new("hmc", "MESH_CACHE")
    modifier.cache_format = "PC2" if cache_path.lower().endswith(
        ".pc2") else "MDD"
    modifier.filepath = os.path.abspath(cache_path)
    modifier.forward_axis = CACHE_FORWARD
    modifier.up_axis = CACHE_UP
    modifier.time_mode = "FRAME"
    modifier.play_mode = "SCENE"
    modifier.frame_start = start   # scene frame `start` = the cache's first
    modifier.frame_scale = 1.0
    modifier.interpolation = "NONE"
    modifier.deform_mode = "OVERWRITE"

    scene = bpy.context.scene
    scene.frame_start = start
    scene.frame_end = start + frames - 1
    scene.frame_set(frame)
    evaluated = local_coords(neutral, evaluated=True)
    rest = local_coords(neutral, evaluated=False)

    expected_obj = import_obj(os.path.abspath(expected_path))
    expected = local_coords(expected_obj, evaluated=False)
    if len(expected) != len(evaluated):
        print(f"MISMATCH: {expected_path} has {len(expected)} vertices, the "
              f"evaluated mesh {len(evaluated)}")
        return 1

    difference = max_difference(evaluated, expected)
    moved = max_difference(evaluated, rest)
    scale = max(abs(x) for p in expected for x in p)
    # Both sides are float32 copies of the same float32 values (the cache
    # holds float32; Blender parses OBJ text to float32): allow a few float32
    # ulps of the largest coordinate for the text parse.
    tolerance = 4 * 2.0 ** -23 * max(scale, 1.0)
    print(f"frame {frame}: max |evaluated - expected| = {difference:.9g} "
          f"(tolerance {tolerance:.3g}); max |evaluated - neutral| = "
          f"{moved:.9g}; largest coordinate {scale:.6g}")
    if not math.isfinite(difference) or difference > tolerance:
        print("MISMATCH")
        return 1
    print("OK")
    return 0


if __name__ == "__main__":
    try:
        argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
        code = main(argv)
    except Exception:  # report any failure as exit code 2, not a hang
        traceback.print_exc()
        code = 2
    sys.stdout.flush()
    sys.exit(code)
