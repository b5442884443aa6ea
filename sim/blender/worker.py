"""The Blender side of the renderer: run as ``python worker.py JOB_DIR`` under the Blender environment's Python.

It imports only the standard library, numpy (1.x there: bpy 4.5 pins numpy < 2) and bpy, never ``dptpu``. The
job folder holds ``job.json`` (written by :mod:`dptpu.sim.blender.job`, every length in metres) and ``.npy``
arrays; the worker renders one frame per projector pattern with Cycles on the CPU and writes ``frames.npy``
(N, H, W) float32, the linear radiance of each pixel (no view transform, exposure 0), and ``stats.json``.

Scene: a perspective camera from the intrinsics (``lens``, horizontal sensor fit, ``shift_x``, ``shift_y``) and a
spot light as the projector. The light's shader turns the direction of each shading point in the light's frame
(Texture Coordinate ``Normal``: unit vector, light looks down -Z, +Y up) into the projector pixel through the
projector's full model, as the projector's inverse-camera calibration defines it::

    x = d_x / -d_z,  y = d_y / d_z                      (OpenCV axes: y down, z forward)
    (x_d, y_d) = Brown-Conrady distortion of (x, y)      (k1 k2 p1 p2 k3)
    u = fx x_d + s y_d + cx,  v = fy y_d + cy            (K with skew, 0-based pixel centres)
    U = (u + 0.5) / W_p,  V = 1 - (v + 0.5) / H_p        (Blender image coordinates, V up)

and emits the pattern's value there (image texture, linear interpolation) on the panel ``0 < U, V < 1`` and nothing
off it. A pattern constant along one axis (vertical or horizontal fringes) comes as one row or one column, which
the texture extends over the panel: a 4 MB image per frame less to build.

Traps of bpy 4.5 this avoids: an image's colour space is set (Non-Color) before its pixels are written (changing it
afterwards blanks the image); each pattern gets a new image datablock (rewriting the pixels of the same image
between renders is ignored).
"""
import json
import os
import sys
import time

import numpy as np


def _load(job_dir, name):
    return np.load(os.path.join(job_dir, name))


def _math(tree, operation, a, b=None):
    """A Math node computing ``a <op> b``; a and b are sockets or numbers. Returns the output socket."""
    node = tree.nodes.new("ShaderNodeMath")
    node.operation = operation
    for index, value in enumerate((a, b)):
        if value is None:
            continue
        if isinstance(value, (int, float)):
            node.inputs[index].default_value = float(value)
        else:
            tree.links.new(value, node.inputs[index])
    return node.outputs[0]


def _polynomial(tree, terms):
    """Sum of ``coefficient * socket`` terms; a term with socket None is a constant. Returns the output socket."""
    constant = sum(coefficient for coefficient, socket in terms if socket is None)
    total = None
    for coefficient, socket in terms:
        if socket is None or coefficient == 0.0:
            continue
        term = socket if coefficient == 1.0 else _math(tree, "MULTIPLY", socket, float(coefficient))
        total = term if total is None else _math(tree, "ADD", total, term)
    if total is None:
        return _math(tree, "ADD", float(constant), 0.0)
    return total if constant == 0.0 else _math(tree, "ADD", total, float(constant))


def _projector_uv(tree, projector):
    """Shader nodes from the light's Normal coordinate to the pattern's (U, V, 0) vector socket and the panel
    mask socket (1 on the projector's image, 0 off it)."""
    coordinates = tree.nodes.new("ShaderNodeTexCoord")
    split = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(coordinates.outputs["Normal"], split.inputs[0])
    d_x, d_y, d_z = split.outputs[0], split.outputs[1], split.outputs[2]
    x = _math(tree, "DIVIDE", d_x, _math(tree, "MULTIPLY", d_z, -1.0))
    y = _math(tree, "DIVIDE", d_y, d_z)
    k1, k2, p1, p2, k3 = (float(v) for v in projector["dist"])
    if any((k1, k2, p1, p2, k3)):
        xx, yy, xy = _math(tree, "MULTIPLY", x, x), _math(tree, "MULTIPLY", y, y), _math(tree, "MULTIPLY", x, y)
        r2 = _math(tree, "ADD", xx, yy)
        r4 = _math(tree, "MULTIPLY", r2, r2)
        r6 = _math(tree, "MULTIPLY", r4, r2)
        radial = _polynomial(tree, [(1.0, None), (k1, r2), (k2, r4), (k3, r6)])
        # x_d = x radial + 2 p1 x y + p2 (r2 + 2 x^2);  y_d = y radial + p1 (r2 + 2 y^2) + 2 p2 x y
        x_d = _polynomial(tree, [(1.0, _math(tree, "MULTIPLY", x, radial)), (2.0 * p1, xy), (p2, r2), (2.0 * p2, xx)])
        y_d = _polynomial(tree, [(1.0, _math(tree, "MULTIPLY", y, radial)), (p1, r2), (2.0 * p1, yy), (2.0 * p2, xy)])
    else:
        x_d, y_d = x, y
    (fx, skew, cx), (_, fy, cy) = projector["K"][0], projector["K"][1]
    width, height = projector["size"]
    # U = (fx x_d + s y_d + cx + 0.5) / W;  V = 1 - (fy y_d + cy + 0.5) / H
    U = _polynomial(tree, [(fx / width, x_d), (skew / width, y_d), ((cx + 0.5) / width, None)])
    V = _polynomial(tree, [(-fy / height, y_d), (1.0 - (cy + 0.5) / height, None)])
    combine = tree.nodes.new("ShaderNodeCombineXYZ")
    tree.links.new(U, combine.inputs[0])
    tree.links.new(V, combine.inputs[1])
    # the panel: 1 where 0 < U < 1 and 0 < V < 1 (projector pixels -0.5 .. W - 0.5), else 0
    inside = [_math(tree, "GREATER_THAN", U, 0.0), _math(tree, "LESS_THAN", U, 1.0),
              _math(tree, "GREATER_THAN", V, 0.0), _math(tree, "LESS_THAN", V, 1.0)]
    panel = _math(tree, "MULTIPLY", _math(tree, "MULTIPLY", inside[0], inside[1]),
                  _math(tree, "MULTIPLY", inside[2], inside[3]))
    return combine.outputs[0], panel


def _new_image(bpy, name, values):
    """A float image datablock holding ``values`` (H, W) grey in [0, 1], row 0 at the top; Non-Color."""
    height, width = values.shape
    image = bpy.data.images.new(name, width, height, alpha=False, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"  # before the pixels: changing it afterwards blanks the image
    rgba = np.empty((height, width, 4), dtype=np.float32)
    rgba[..., :3] = np.ascontiguousarray(values[::-1], dtype=np.float32)[..., None]  # Blender rows go up
    rgba[..., 3] = 1.0
    image.pixels.foreach_set(rgba.ravel())
    image.update()
    return image


def _vertex_normals(vertices, triangles):
    """Area-weighted unit vertex normals (V, 3), the shading normals of the raycast renderer too."""
    v0, v1, v2 = (vertices[triangles[:, i]].astype(np.float64) for i in range(3))
    face = np.cross(v1 - v0, v2 - v0)  # (T, 3), length = 2 * area
    normals = np.zeros((len(vertices), 3))
    for i in range(3):
        np.add.at(normals, triangles[:, i], face)
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)


def _add_mesh(bpy, scene, job_dir, entry):
    vertices = _load(job_dir, entry["vertices"]).astype(np.float32)  # (V, 3), metres
    triangles = _load(job_dir, entry["triangles"]).astype(np.int32)  # (T, 3)
    mesh = bpy.data.meshes.new(entry["name"])
    mesh.vertices.add(len(vertices))
    mesh.vertices.foreach_set("co", vertices.ravel())
    mesh.loops.add(triangles.size)
    mesh.loops.foreach_set("vertex_index", triangles.ravel())
    mesh.polygons.add(len(triangles))
    mesh.polygons.foreach_set("loop_start", np.arange(0, triangles.size, 3, dtype=np.int32))
    if entry.get("uv"):
        uv = _load(job_dir, entry["uv"]).astype(np.float32)  # (V, 2), v down the texture image
        layer = mesh.uv_layers.new(name="UVMap")
        corner_uv = uv[triangles.ravel()]
        corner_uv[:, 1] = 1.0 - corner_uv[:, 1]  # Blender's V goes up
        layer.data.foreach_set("uv", corner_uv.ravel())
    mesh.update()
    mesh.polygons.foreach_set("use_smooth", np.ones(len(triangles), dtype=bool))
    mesh.normals_split_custom_set_from_vertices(_vertex_normals(vertices, triangles).tolist())
    mesh.update()
    material = bpy.data.materials.new(entry["name"])
    material.use_nodes = True
    bsdf = material.node_tree.nodes["Principled BSDF"]
    albedo = float(entry["albedo"])
    bsdf.inputs["Base Color"].default_value = (albedo, albedo, albedo, 1.0)
    bsdf.inputs["Roughness"].default_value = float(entry["roughness"])
    bsdf.inputs["IOR"].default_value = float(entry["ior"])
    bsdf.inputs["Specular IOR Level"].default_value = 0.5 * float(entry["specular"])
    bsdf.inputs["Metallic"].default_value = 0.0
    if entry.get("texture"):
        texture = _load(job_dir, entry["texture"])  # (Ht, Wt) in [0, 1]
        node = material.node_tree.nodes.new("ShaderNodeTexImage")
        node.image = _new_image(bpy, entry["name"] + "_albedo", np.clip(texture, 0.0, 1.0))
        node.interpolation = "Linear"  # bilinear, texel centres at (i + 0.5) / W
        node.extension = "EXTEND"  # clamped at the edge, as the raycast twin
        scaled = material.node_tree.nodes.new("ShaderNodeMixRGB")
        scaled.blend_type = "MULTIPLY"
        scaled.inputs[0].default_value = 1.0
        material.node_tree.links.new(node.outputs["Color"], scaled.inputs[1])
        scaled.inputs[2].default_value = (albedo, albedo, albedo, 1.0)
        material.node_tree.links.new(scaled.outputs[0], bsdf.inputs["Base Color"])
    mesh.materials.append(material)
    obj = bpy.data.objects.new(entry["name"], mesh)
    scene.collection.objects.link(obj)
    return obj


def _place(obj, entry):
    obj.location = entry["location_m"]
    obj.rotation_mode = "XYZ"
    obj.rotation_euler = entry["rotation_euler_rad"]


def build_scene(bpy, job, job_dir):
    """The whole scene of a job; returns (scene, image texture node of the projector)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    render = job["render"]
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = int(render["samples"])
    scene.cycles.seed = int(render["seed"])
    scene.cycles.use_animated_seed = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.pixel_filter_type = "BOX"  # a sensor pixel integrates over its own area
    scene.cycles.filter_width = 1.0
    bounces = int(render["max_bounces"])
    scene.cycles.max_bounces = bounces
    scene.cycles.diffuse_bounces = bounces
    scene.cycles.glossy_bounces = bounces
    scene.cycles.transmission_bounces = bounces
    scene.cycles.transparent_max_bounces = bounces
    scene.cycles.sample_clamp_direct = 0.0
    scene.cycles.sample_clamp_indirect = 0.0
    scene.render.use_persistent_data = True
    scene.render.threads_mode = "FIXED"
    scene.render.threads = int(render["threads"])
    scene.render.resolution_x, scene.render.resolution_y = (int(v) for v in job["resolution"])
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.cycles.film_exposure = 1.0
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    settings.color_mode = "RGB"
    settings.exr_codec = "NONE"

    world = bpy.data.worlds.new("ambient")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    level = float(render["ambient_radiance"])
    background.inputs["Color"].default_value = (level, level, level, 1.0)
    background.inputs["Strength"].default_value = 1.0
    world.cycles_visibility.camera = False  # ambient light on surfaces; the empty background reads 0
    scene.world = world

    entry = job["camera"]
    camera = bpy.data.cameras.new("camera")
    camera.type = "PERSP"
    camera.sensor_fit = "HORIZONTAL"
    camera.sensor_width = float(entry["sensor_width_mm"])
    camera.lens = float(entry["lens_mm"])
    camera.shift_x, camera.shift_y = float(entry["shift_x"]), float(entry["shift_y"])
    camera.clip_start, camera.clip_end = float(entry["clip_start_m"]), float(entry["clip_end_m"])
    camera_object = bpy.data.objects.new("camera", camera)
    _place(camera_object, entry)
    scene.collection.objects.link(camera_object)
    scene.camera = camera_object

    entry = job["projector"]
    light = bpy.data.lights.new("projector", "SPOT")
    light.energy = float(entry["power_w"])
    light.spot_size = float(entry["spot_size_rad"])
    light.spot_blend = 0.0
    light.shadow_soft_size = 0.0  # a pinhole projector: sharp shadows
    light.use_nodes = True
    tree = light.node_tree
    emission = tree.nodes["Emission"]
    emission.inputs["Strength"].default_value = 1.0
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.interpolation = entry.get("interpolation", "Linear")
    texture.extension = "EXTEND"  # a pattern of one row (or column) holds for the whole panel; the mask clips
    uv, panel = _projector_uv(tree, entry)
    tree.links.new(uv, texture.inputs["Vector"])
    tree.links.new(texture.outputs["Color"], emission.inputs["Color"])
    tree.links.new(panel, emission.inputs["Strength"])
    light_object = bpy.data.objects.new("projector", light)
    _place(light_object, entry)
    scene.collection.objects.link(light_object)

    for mesh_entry in job["meshes"]:
        _add_mesh(bpy, scene, job_dir, mesh_entry)
    return scene, texture


def _read_exr(bpy, path, shape):
    image = bpy.data.images.load(path)
    pixels = np.empty(shape[0] * shape[1] * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return pixels.reshape(shape[0], shape[1], 4)[::-1, :, :3].mean(axis=-1)  # (H, W), row 0 at the top


def main(job_dir):
    started = time.perf_counter()
    with open(os.path.join(job_dir, "job.json")) as handle:
        job = json.load(handle)
    import bpy  # only inside Blender's Python

    scene, texture = build_scene(bpy, job, job_dir)
    patterns = np.load(os.path.join(job_dir, job["patterns"]), mmap_mode="r")  # (N, Hp, Wp), (N, 1, Wp) or (N, Hp, 1)
    width, height = (int(v) for v in job["resolution"])
    frames = np.zeros((len(patterns), height, width), dtype=np.float32)
    exr = os.path.join(job_dir, "frame.exr")
    scene.render.filepath = exr
    setup_s = time.perf_counter() - started
    seconds, cpu_seconds = [], []
    previous = None
    for index in range(len(patterns)):
        tick, tick_cpu = time.perf_counter(), time.process_time()
        image = _new_image(bpy, f"pattern_{index:04d}", np.asarray(patterns[index], dtype=np.float32))
        texture.image = image  # a new datablock per pattern: rewriting one image's pixels is ignored
        scene.cycles.seed = int(job["render"]["seed"]) + index  # independent sampling noise per frame
        if previous is not None:
            bpy.data.images.remove(previous)
        previous = image
        bpy.ops.render.render(write_still=True)
        frames[index] = _read_exr(bpy, exr, (height, width))
        seconds.append(time.perf_counter() - tick)
        cpu_seconds.append(time.process_time() - tick_cpu)
    np.save(os.path.join(job_dir, job["output"]), frames)
    stats = {"bpy_version": bpy.app.version_string, "setup_s": setup_s, "seconds_per_frame": seconds,
             "cpu_seconds_per_frame": cpu_seconds,
             "frames": len(patterns), "resolution": [width, height], "samples": job["render"]["samples"]}
    with open(os.path.join(job_dir, "stats.json"), "w") as handle:
        json.dump(stats, handle)
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.stderr.write("usage: python worker.py JOB_DIR\n")
        sys.exit(2)
    sys.exit(main(sys.argv[1]))
