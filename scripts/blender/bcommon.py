"""Blender helpers shared by the world generator and the units check:
scene reset, Cycles settings, geometry in OUR coordinates (Y up), materials,
renders read back as numpy arrays (row 0 = top)."""
import math
import os
import sys
import tempfile
import time

import bmesh
import bpy
import numpy as np

import exrio
import units

EMITTER_AOV = "emitter"
COAT_MIX = "propcam_coat_mix"


def coats(on):
    """Turns every plastic coat on (Fresnel-mixed) or off (pure diffuse base):
    off for the DiffCol pass, which Cycles weights by the mix (1 - F)."""
    for m in bpy.data.materials:
        if not m.use_nodes:
            continue
        nt = m.node_tree
        for node in nt.nodes:
            if node.name.startswith(COAT_MIX):
                fr = [n for n in nt.nodes if n.bl_idname == "ShaderNodeFresnel"][0]
                for link in list(node.inputs[0].links):
                    nt.links.remove(link)
                if on:
                    nt.links.new(fr.outputs[0], node.inputs[0])


# --- scene -------------------------------------------------------------------
def reset_scene(width, height, threads):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    cy = sc.cycles
    cy.device = "CPU"
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.use_preview_denoising = False
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.blur_glossy = 0.0
    cy.light_sampling_threshold = 0.0
    # no caustic paths (glossy/refractive after a diffuse bounce): their
    # fireflies outweigh the light they carry (docs/blender_world.md)
    cy.caustics_reflective = False
    cy.caustics_refractive = False
    cy.max_bounces = 8
    cy.diffuse_bounces = 8
    cy.glossy_bounces = 8
    cy.transmission_bounces = 8
    cy.transparent_max_bounces = 8
    cy.volume_bounces = 0
    cy.use_animated_seed = False
    sc.render.resolution_x = width
    sc.render.resolution_y = height
    sc.render.resolution_percentage = 100
    sc.render.threads_mode = "FIXED"
    sc.render.threads = max(1, threads)
    sc.render.use_compositing = False
    sc.render.use_persistent_data = True  # renders of one scene reuse the synced scene
    sc.render.use_sequencer = False
    sc.render.film_transparent = False
    sc.view_settings.view_transform = "Standard"
    sc.view_settings.look = "None"
    sc.view_settings.exposure = 0.0
    sc.view_settings.gamma = 1.0
    sc.display_settings.display_device = "sRGB"
    sc.sequencer_colorspace_settings.name = "Linear"
    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    sc.world = world
    set_world_color((0.0, 0.0, 0.0), 0.0)
    vl = sc.view_layers[0]
    vl.use_pass_combined = True
    # every pass from the start: with persistent data a pass switched on
    # between renders of one scene is not picked up
    vl.use_pass_z = vl.use_pass_normal = vl.use_pass_diffuse_color = vl.use_pass_object_index = True
    aov = vl.aovs.add()
    aov.name = EMITTER_AOV
    aov.type = "VALUE"
    return sc


def set_world_color(color, strength):
    nt = bpy.context.scene.world.node_tree
    nt.nodes.clear()
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs[0].default_value = tuple(color) + (1.0,)
    bg.inputs[1].default_value = strength
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(bg.outputs[0], out.inputs[0])


def set_world_environment(exr_path, strength):
    """An equirectangular map in OUR convention as the world (rotated so that
    Blender looks it up our way)."""
    nt = bpy.context.scene.world.node_tree
    nt.nodes.clear()
    tc = nt.nodes.new("ShaderNodeTexCoord")
    mp = nt.nodes.new("ShaderNodeMapping")
    mp.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(units.ENV_MAPPING_Z_DEG))
    tex = nt.nodes.new("ShaderNodeTexEnvironment")
    tex.image = bpy.data.images.load(exr_path)
    tex.image.colorspace_settings.name = "Linear"
    tex.interpolation = "Closest"
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs[1].default_value = strength
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(tc.outputs["Generated"], mp.inputs["Vector"])
    nt.links.new(mp.outputs["Vector"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs[0], out.inputs[0])


def set_camera(R_world_from_cam, center, fx, width, height, name="camera"):
    sc = bpy.context.scene
    cam = bpy.data.cameras.new(name)
    cam.sensor_fit = "HORIZONTAL" if width >= height else "VERTICAL"
    cam.sensor_width = 36.0
    cam.sensor_height = 36.0
    cam.lens = units.blender_lens_mm(fx, max(width, height) if width >= height else height)
    if width < height:
        cam.lens = fx * 36.0 / height
    cam.shift_x = cam.shift_y = 0.0
    cam.clip_start = 0.01
    cam.clip_end = 1.0e5
    obj = bpy.data.objects.new(name, cam)
    sc.collection.objects.link(obj)
    from mathutils import Matrix
    obj.matrix_world = Matrix(units.blender_camera_matrix(R_world_from_cam, center).tolist())
    sc.camera = obj
    return obj


def set_pano_camera(center_ours, name="probe"):
    cam = bpy.data.cameras.new(name)
    cam.type = "PANO"
    cam.cycles.panorama_type = "EQUIRECTANGULAR"
    cam.clip_start = 1e-3
    cam.clip_end = 1.0e5
    obj = bpy.data.objects.new(name, cam)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = units.to_blender(center_ours)
    obj.rotation_euler = tuple(math.radians(a) for a in units.PANO_CAMERA_EULER_DEG)
    return obj


# --- geometry (our coordinates) --------------------------------------------
def mesh_object(name, verts_ours, faces, material=None, collection=None):
    me = bpy.data.meshes.new(name)
    me.from_pydata([units.to_blender(v) for v in verts_ours], [], faces)
    me.validate()
    me.update()
    obj = bpy.data.objects.new(name, me)
    (collection or bpy.context.scene.collection).objects.link(obj)
    if material is not None:
        me.materials.append(material)
    return obj


def box(name, lo, hi, material=None):
    """Axis-aligned box in our coordinates, outward faces."""
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0), (x0, y0, z1), (x1, y0, z1), (x1, y1, z1),
         (x0, y1, z1)]
    # winding in our (right-handed) coordinates, outward
    f = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (3, 7, 6, 2), (0, 4, 7, 3), (1, 2, 6, 5)]
    return mesh_object(name, v, f, material)


def quad(name, corner, edge_u, edge_v, material=None):
    """One-sided quad: front (normal) = edge_u x edge_v."""
    c = np.asarray(corner, float)
    u = np.asarray(edge_u, float)
    w = np.asarray(edge_v, float)
    return mesh_object(name, [c, c + u, c + u + w, c + w], [(0, 1, 2, 3)], material)


def uv_sphere(name, center, radius, material=None, segments=32, rings=16):
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=radius)
    bm.to_mesh(me)
    bm.free()
    obj = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = units.to_blender(center)
    for p in me.polygons:
        p.use_smooth = True
    if material is not None:
        me.materials.append(material)
    return obj


def frustum(name, center_bottom, r_bottom, r_top, height, material=None, segments=32, open_ends=True):
    """Vertical open cylinder/cone (ours: along +Y), faces outward."""
    cx, cy, cz = center_bottom
    verts, faces = [], []
    for i in range(segments):
        a = 2 * math.pi * i / segments
        verts.append((cx + r_bottom * math.cos(a), cy, cz + r_bottom * math.sin(a)))
        verts.append((cx + r_top * math.cos(a), cy + height, cz + r_top * math.sin(a)))
    for i in range(segments):
        j = (i + 1) % segments
        faces.append((2 * i, 2 * i + 1, 2 * j + 1, 2 * j))
    if not open_ends:
        faces.append(tuple(2 * i for i in range(segments)))
        faces.append(tuple(2 * i + 1 for i in reversed(range(segments))))
    obj = mesh_object(name, verts, faces, material)
    for p in obj.data.polygons:
        p.use_smooth = True
    # outward: check one face against the axis
    return obj


def disc(name, center, radius, facing_up, material=None, segments=32):
    """Horizontal one-sided disc (ours: normal +Y when facing_up, else -Y)."""
    cx, cy, cz = center
    ring = [(cx + radius * math.cos(2 * math.pi * i / segments), cy, cz + radius * math.sin(2 * math.pi * i / segments))
            for i in range(segments)]
    # increasing angle (x toward z) winds toward -Y in our right-handed axes
    face = tuple(range(segments)) if not facing_up else tuple(reversed(range(segments)))
    return mesh_object(name, ring, [face], material)


def camera_only(obj):
    """Visible to camera rays only: no light from it along other paths (a light
    object at its place carries it), no shadows, not an NEE emitter."""
    obj.visible_diffuse = obj.visible_glossy = obj.visible_transmission = False
    obj.visible_volume_scatter = obj.visible_shadow = False
    return obj


def area_light(name, center_ours, normal_ours, axis_u_ours, size_u, size_v, color, radiance_scale, disk=False):
    """A Cycles AREA light (RECTANGLE size_u x size_v along axis_u, or DISK of
    diameter size_u) emitting radiance colour * radiance_scale toward
    normal_ours (one-sided): power = 4 A x radiance (units.area_light_power)."""
    n = np.asarray(normal_ours, float)
    n /= np.linalg.norm(n)
    u = np.asarray(axis_u_ours, float)
    u = u - n * (u @ n)
    u /= np.linalg.norm(u)
    area = math.pi * size_u ** 2 / 4.0 if disk else size_u * size_v
    lamp = bpy.data.lights.new(name, "AREA")
    lamp.shape = "DISK" if disk else "RECTANGLE"
    lamp.size = float(size_u)
    if not disk:
        lamp.size_y = float(size_v)
    lamp.color = tuple(float(c) for c in color)
    lamp.energy = units.area_light_power(radiance_scale, area)
    obj = bpy.data.objects.new(name, lamp)
    bpy.context.scene.collection.objects.link(obj)
    # local -Z = the normal, local X = axis_u, local Y = Z x X
    zb = -np.asarray(units.to_blender(n))
    xb = np.asarray(units.to_blender(u))
    yb = np.cross(zb, xb)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = xb, yb, zb
    m[:3, 3] = units.to_blender(center_ours)
    from mathutils import Matrix
    obj.matrix_world = Matrix(m.tolist())
    return obj, lamp.energy


def point_light(name, center_ours, radius, color, radiance_scale):
    """A Cycles POINT light of soft radius r: our sphere of radius r and
    radiance colour * radiance_scale (power = 4 pi^2 r^2 x radiance)."""
    lamp = bpy.data.lights.new(name, "POINT")
    lamp.shadow_soft_size = float(radius)
    lamp.color = tuple(float(c) for c in color)
    lamp.energy = 4.0 * math.pi ** 2 * radius ** 2 * radiance_scale
    obj = bpy.data.objects.new(name, lamp)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = units.to_blender(center_ours)
    return obj, lamp.energy


def portal(name, center_ours, inward_ours, width, height):
    """A Cycles light portal (an AREA light with is_portal) filling a window
    opening: width along the horizontal, height along Y, its light direction
    (local -Z) pointing into the room. Not an emitter: it only guides the
    sampling of the world through the opening; invisible to every ray."""
    from mathutils import Vector
    lamp = bpy.data.lights.new(name, "AREA")
    lamp.shape = "RECTANGLE"
    lamp.size = float(width)
    lamp.size_y = float(height)
    lamp.cycles.is_portal = True
    obj = bpy.data.objects.new(name, lamp)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = units.to_blender(center_ours)
    d = -np.asarray(units.to_blender(inward_ours), float)
    # local +Z away from the room, local Y as close to up as possible
    obj.rotation_euler = Vector(d.tolist()).to_track_quat("Z", "Y").to_euler()
    return obj


def cylinder(name, center_bottom, radius, height, material=None, segments=24):
    return frustum(name, center_bottom, radius, radius, height, material, segments, open_ends=False)


def mesh_area(obj):
    return sum(p.area for p in obj.data.polygons) * abs(np.linalg.det(np.asarray(obj.matrix_world)[:3, :3])) ** (2 / 3)


# --- materials ---------------------------------------------------------------
def _new_material(name):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    return m, nt, out


def _aov(nt, value):
    a = nt.nodes.new("ShaderNodeOutputAOV")
    a.name = EMITTER_AOV  # the node name is the AOV name
    a.inputs["Value"].default_value = value
    return a


def diffuse_material(name, color, emitter_aov=False):
    m, nt, out = _new_material(name)
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = tuple(color) + (1.0,)
    d.inputs["Roughness"].default_value = 0.0
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    if emitter_aov:
        _aov(nt, 1.0)
    return m


def plastic_material(name, color, specular_f0, alpha, color_socket=None, nt_m=None):
    """Our `plastic`: a Lambertian base under a GGX coat with normal-incidence
    reflectance F0 (coat index n from F0 = ((n-1)/(n+1))^2): Fresnel(n) mixes a
    Diffuse BSDF and a white GGX Glossy BSDF of Blender roughness sqrt(alpha)."""
    m, nt, out = nt_m if nt_m else _new_material(name)
    f0 = min(max(specular_f0, 1e-4), 0.99)
    n = (1 + math.sqrt(f0)) / (1 - math.sqrt(f0))
    fr = nt.nodes.new("ShaderNodeFresnel")
    fr.inputs["IOR"].default_value = n
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Roughness"].default_value = 0.0
    if color_socket is not None:
        nt.links.new(color_socket, d.inputs["Color"])
    else:
        d.inputs["Color"].default_value = tuple(color) + (1.0,)
    g = nt.nodes.new("ShaderNodeBsdfGlossy")
    g.distribution = "GGX"
    g.inputs["Color"].default_value = (1, 1, 1, 1)
    g.inputs["Roughness"].default_value = math.sqrt(max(alpha, 0.0))
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.name = COAT_MIX
    mix.inputs[0].default_value = 0.0
    nt.links.new(fr.outputs[0], mix.inputs[0])
    nt.links.new(d.outputs[0], mix.inputs[1])
    nt.links.new(g.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    return m


def metal_material(name, f0, alpha):
    m, nt, out = _new_material(name)
    p = nt.nodes.new("ShaderNodeBsdfPrincipled")
    p.distribution = "GGX"
    p.inputs["Base Color"].default_value = tuple(f0) + (1.0,)
    p.inputs["Metallic"].default_value = 1.0
    p.inputs["Roughness"].default_value = math.sqrt(max(alpha, 0.0))
    nt.links.new(p.outputs[0], out.inputs["Surface"])
    return m


def glass_material(name, ior, alpha):
    m, nt, out = _new_material(name)
    g = nt.nodes.new("ShaderNodeBsdfGlass")
    g.distribution = "GGX"
    g.inputs["IOR"].default_value = ior
    g.inputs["Roughness"].default_value = math.sqrt(max(alpha, 0.0))
    nt.links.new(g.outputs[0], out.inputs["Surface"])
    return m


def emission_material(name, color, strength, one_sided=True, emitter_aov=True, reflectance=None):
    """Radiance = strength * colour on the front side (the side the face normal
    points to); the back side is black (absorbing). reflectance: the front
    also reflects diffusely with this albedo (a glowing fabric)."""
    m, nt, out = _new_material(name)
    e = nt.nodes.new("ShaderNodeEmission")
    e.inputs["Color"].default_value = tuple(color) + (1.0,)
    e.inputs["Strength"].default_value = strength
    if reflectance is not None:
        d = nt.nodes.new("ShaderNodeBsdfDiffuse")
        d.inputs["Color"].default_value = tuple(reflectance) + (1.0,)
        d.inputs["Roughness"].default_value = 0.0
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(e.outputs[0], add.inputs[0])
        nt.links.new(d.outputs[0], add.inputs[1])
        e = add
    if one_sided:
        geo = nt.nodes.new("ShaderNodeNewGeometry")
        black = nt.nodes.new("ShaderNodeBsdfDiffuse")
        black.inputs["Color"].default_value = (0, 0, 0, 1)
        mix = nt.nodes.new("ShaderNodeMixShader")
        nt.links.new(geo.outputs["Backfacing"], mix.inputs[0])
        nt.links.new(e.outputs[0], mix.inputs[1])
        nt.links.new(black.outputs[0], mix.inputs[2])
        nt.links.new(mix.outputs[0], out.inputs["Surface"])
    else:
        nt.links.new(e.outputs[0], out.inputs["Surface"])
    if emitter_aov:
        _aov(nt, 1.0)
    return m


def prop_material(name, spec):
    """A material of an exported preset prop (<name>.materials.json entry)."""
    t = spec["type"]
    alb = spec.get("albedo", [0.5, 0.5, 0.5])
    a = float(spec.get("roughness", 1.0))
    if t == "diffuse":
        return diffuse_material(name, alb)
    if t in ("plastic", "glossy"):
        return plastic_material(name, alb, float(spec.get("specular", 0.04)), a)
    if t in ("metal", "conductor"):
        return metal_material(name, alb, a)
    if t in ("dielectric", "glass"):
        return glass_material(name, float(spec.get("ior", 1.5)), a)
    if t == "emissive":
        return emission_material(name, spec.get("emission", [1, 1, 1]), 1.0, one_sided=False)
    raise ValueError("unknown material type " + t)


# --- rendering ---------------------------------------------------------------
def _tmpdir():
    d = os.environ.get("PROPCAM_BLENDER_TMP") or tempfile.mkdtemp(prefix="propcam_blender_")
    os.makedirs(d, exist_ok=True)
    return d


def render_layers(spp, seed, passes=(), camera=None, resolution=None, filter_px=None, max_bounces=None):
    """Renders the scene; returns ({layer: H x W (x C) array}, seconds).
    passes: names among 'depth', 'normal', 'diffcol', 'index', 'aov'.
    filter_px: Cycles pixel filter width (None: Blackman-Harris 1.5 px); a
    width of 0.01 samples every pixel at its centre (exact passes)."""
    sc = bpy.context.scene
    if camera is not None:
        sc.camera = camera
    if resolution is not None:
        sc.render.resolution_x, sc.render.resolution_y = resolution
    cy = sc.cycles
    cy.samples = int(spp)
    cy.seed = int(seed) & 0x7FFFFFFF
    if max_bounces is not None:
        cy.max_bounces = max_bounces
    if filter_px is None:
        cy.pixel_filter_type = "BLACKMAN_HARRIS"
        cy.filter_width = 1.5
    else:
        cy.pixel_filter_type = "BOX"
        cy.filter_width = filter_px
    vl = sc.view_layers[0]
    r = sc.render
    r.image_settings.file_format = "OPEN_EXR_MULTILAYER"
    r.image_settings.color_depth = "32"
    r.image_settings.exr_codec = "ZIP"
    path = os.path.join(_tmpdir(), "render_%d.exr" % os.getpid())
    r.filepath = path
    t0 = time.time()
    bpy.ops.render.render(write_still=True)
    secs = time.time() - t0
    ch = exrio.read_exr(path)
    os.remove(path)
    layer = vl.name + "."

    def rgb(pfx):
        return np.stack([ch[layer + pfx + ".R"], ch[layer + pfx + ".G"], ch[layer + pfx + ".B"]], axis=2)

    out = {"combined": rgb("Combined")}
    if "depth" in passes:
        out["depth"] = ch[layer + "Depth.Z"]
    if "normal" in passes:
        out["normal"] = np.stack([ch[layer + "Normal.X"], ch[layer + "Normal.Y"], ch[layer + "Normal.Z"]], axis=2)
    if "diffcol" in passes:
        out["diffcol"] = rgb("DiffCol")
    if "index" in passes:
        out["index"] = ch[layer + "IndexOB.X"]
    if "aov" in passes:
        key = [k for k in ch if k.startswith(layer + EMITTER_AOV)]
        if not key:
            raise RuntimeError("no %s AOV in the render (channels: %s)" % (EMITTER_AOV, sorted(ch)))
        out["aov"] = ch[key[0]]
    return out, secs


def save_display_image(linear_rgb, path, view_transform, quality=None):
    """Writes linear scene-referred RGB through Blender's view transform
    (Standard = sRGB, or Filmic) to an 8-bit PNG, or a JPEG of `quality`."""
    sc = bpy.context.scene
    h, w = linear_rgb.shape[:2]
    img = bpy.data.images.new("display_%d" % len(bpy.data.images), w, h, float_buffer=True, alpha=False)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = linear_rgb[::-1]
    img.pixels.foreach_set(rgba.ravel())
    sc.view_settings.view_transform = view_transform
    sc.view_settings.look = "None"
    sc.view_settings.exposure = 0.0
    sc.view_settings.gamma = 1.0
    s = sc.render.image_settings
    if quality is None:
        s.file_format = "PNG"
        s.color_mode = "RGB"
        s.color_depth = "8"
        s.compression = 15
    else:
        s.file_format = "JPEG"
        s.color_mode = "RGB"
        s.quality = int(quality)
    img.save_render(path, scene=sc)
    bpy.data.images.remove(img)


def save_mask_png(mask, path):
    sc = bpy.context.scene
    h, w = mask.shape
    img = bpy.data.images.new("mask_%d" % len(bpy.data.images), w, h, float_buffer=True, alpha=False)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = (mask[::-1, :, None] > 0).astype(np.float32)
    img.pixels.foreach_set(rgba.ravel())
    sc.view_settings.view_transform = "Standard"
    s = sc.render.image_settings
    s.file_format = "PNG"
    s.color_mode = "BW"
    s.color_depth = "8"
    img.save_render(path, scene=sc)
    bpy.data.images.remove(img)


def load_png_8bit(path):
    img = bpy.data.images.load(path)
    img.colorspace_settings.name = "Non-Color"
    h, w = img.size[1], img.size[0]
    a = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(a)
    bpy.data.images.remove(img)
    return np.round(a.reshape(h, w, 4)[::-1, :, :3] * 255.0)


def run_main(main):
    """Runs a script's main() so that an exception ends Blender with status 1
    (Blender itself exits 0 after a failed --python script)."""
    try:
        main()
    except SystemExit:
        raise
    except Exception:
        import traceback
        traceback.print_exc()
        sys.exit(1)
