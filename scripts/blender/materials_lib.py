"""Random surface materials for the Blender world (procedural textures in
world-space metres: objects are built with their vertices in world space)."""
import colorsys

import bcommon


def _tex_coords(nt):
    tc = nt.nodes.new("ShaderNodeTexCoord")
    return tc.outputs["Object"]


def _hsv(h, s, v):
    return list(colorsys.hsv_to_rgb(h % 1.0, min(max(s, 0), 1), min(max(v, 0), 1)))


def random_color(rnd, kind="paint"):
    if kind == "paint":
        return _hsv(rnd.random(), rnd.uniform(0.02, 0.45), rnd.uniform(0.35, 0.9))
    if kind == "wood":
        return _hsv(rnd.uniform(0.05, 0.11), rnd.uniform(0.45, 0.75), rnd.uniform(0.25, 0.6))
    if kind == "dark":
        return _hsv(rnd.random(), rnd.uniform(0.0, 0.5), rnd.uniform(0.05, 0.25))
    if kind == "fabric":
        return _hsv(rnd.random(), rnd.uniform(0.1, 0.7), rnd.uniform(0.15, 0.7))
    if kind == "stone":
        return _hsv(rnd.uniform(0.05, 0.15), rnd.uniform(0.0, 0.2), rnd.uniform(0.25, 0.6))
    raise ValueError(kind)


def _finish(m, nt, out, color_socket, rnd, glossy, summary):
    """Diffuse, or our plastic (Fresnel-mixed coat) when glossy."""
    if glossy:
        f0 = rnd.uniform(0.03, 0.06)
        alpha = rnd.uniform(0.02, 0.3)
        bcommon.plastic_material(m.name, None, f0, alpha, color_socket=color_socket, nt_m=(m, nt, out))
        summary.update({"finish": "glossy", "coat_f0": round(f0, 4), "ggx_alpha": round(alpha, 4)})
    else:
        d = nt.nodes.new("ShaderNodeBsdfDiffuse")
        d.inputs["Roughness"].default_value = 0.0
        nt.links.new(color_socket, d.inputs["Color"])
        nt.links.new(d.outputs[0], out.inputs["Surface"])
        summary["finish"] = "matte"
    return m, summary


def _rgba(c):
    return tuple(c) + (1.0,)


def make(rnd, name, kind, base=None, glossy=None):
    """kind: paint | stripes | wood | tiles | checker | carpet | concrete |
    asphalt | brick. Returns (material, summary dict)."""
    m, nt, out = bcommon._new_material(name)
    summary = {"kind": kind}
    if glossy is None:
        glossy = kind in ("tiles",) or (kind in ("paint", "wood") and rnd.random() < 0.3)
    if kind == "paint":
        c = base or random_color(rnd, "paint")
        rgb = nt.nodes.new("ShaderNodeRGB")
        rgb.outputs[0].default_value = _rgba(c)
        summary["color"] = [round(x, 3) for x in c]
        return _finish(m, nt, out, rgb.outputs[0], rnd, glossy, summary)
    co = _tex_coords(nt)
    if kind in ("stripes", "wood"):
        w = nt.nodes.new("ShaderNodeTexWave")
        w.wave_type = "BANDS"
        w.bands_direction = rnd.choice(["X", "Y", "Z"]) if kind == "stripes" else rnd.choice(["X", "Z"])
        w.wave_profile = "SAW" if kind == "stripes" else "SIN"
        w.inputs["Scale"].default_value = rnd.uniform(1.0, 4.0) if kind == "stripes" else rnd.uniform(6, 15)
        w.inputs["Distortion"].default_value = 0.0 if kind == "stripes" else rnd.uniform(2, 8)
        w.inputs["Detail"].default_value = 2.0
        nt.links.new(co, w.inputs["Vector"])
        ramp = nt.nodes.new("ShaderNodeValToRGB")
        if kind == "stripes":
            ramp.color_ramp.interpolation = "CONSTANT"
            c1, c2 = random_color(rnd, "paint"), random_color(rnd, "paint")
        else:
            c1 = random_color(rnd, "wood")
            c2 = [x * rnd.uniform(0.5, 0.8) for x in c1]
        ramp.color_ramp.elements[0].color = _rgba(c1)
        ramp.color_ramp.elements[1].position = 0.5 if kind == "stripes" else 1.0
        ramp.color_ramp.elements[1].color = _rgba(c2)
        nt.links.new(w.outputs["Fac"], ramp.inputs["Fac"])
        summary["colors"] = [[round(x, 3) for x in c1], [round(x, 3) for x in c2]]
        return _finish(m, nt, out, ramp.outputs["Color"], rnd, glossy, summary)
    if kind in ("tiles", "brick"):
        b = nt.nodes.new("ShaderNodeTexBrick")
        c1 = random_color(rnd, "paint" if kind == "tiles" else "stone")
        if kind == "brick":
            c1 = [c1[0] * 1.3, c1[1] * 0.8, c1[2] * 0.6]
        c2 = [x * rnd.uniform(0.7, 0.95) for x in c1]
        mortar = [rnd.uniform(0.5, 0.8)] * 3
        b.inputs["Color1"].default_value = _rgba(c1)
        b.inputs["Color2"].default_value = _rgba(c2)
        b.inputs["Mortar"].default_value = _rgba(mortar)
        b.inputs["Scale"].default_value = 1.0
        size = rnd.uniform(0.15, 0.5) if kind == "tiles" else rnd.uniform(0.2, 0.3)
        b.inputs["Brick Width"].default_value = size
        b.inputs["Row Height"].default_value = size if kind == "tiles" else size / 3.0
        b.inputs["Mortar Size"].default_value = 0.005 if kind == "tiles" else 0.01
        b.offset = 0.0 if kind == "tiles" else 0.5
        nt.links.new(co, b.inputs["Vector"])
        summary.update({"colors": [[round(x, 3) for x in c1], [round(x, 3) for x in c2]], "tile_m": round(size, 3)})
        return _finish(m, nt, out, b.outputs["Color"], rnd, glossy, summary)
    if kind == "checker":
        ch = nt.nodes.new("ShaderNodeTexChecker")
        c1, c2 = random_color(rnd, "paint"), random_color(rnd, "dark")
        ch.inputs["Color1"].default_value = _rgba(c1)
        ch.inputs["Color2"].default_value = _rgba(c2)
        ch.inputs["Scale"].default_value = rnd.uniform(1.0, 4.0)
        nt.links.new(co, ch.inputs["Vector"])
        summary["colors"] = [[round(x, 3) for x in c1], [round(x, 3) for x in c2]]
        return _finish(m, nt, out, ch.outputs["Color"], rnd, glossy, summary)
    if kind in ("carpet", "concrete", "asphalt"):
        n = nt.nodes.new("ShaderNodeTexNoise")
        n.inputs["Scale"].default_value = {"carpet": 60.0, "concrete": 8.0, "asphalt": 30.0}[kind]
        n.inputs["Detail"].default_value = 6.0
        nt.links.new(co, n.inputs["Vector"])
        if kind == "carpet":
            c1 = random_color(rnd, "fabric")
        elif kind == "concrete":
            g = rnd.uniform(0.3, 0.55)
            c1 = [g, g * 0.98, g * 0.95]
        else:
            g = rnd.uniform(0.07, 0.15)
            c1 = [g, g, g * 1.02]
        c2 = [x * 0.7 for x in c1]
        ramp = nt.nodes.new("ShaderNodeValToRGB")
        ramp.color_ramp.elements[0].position = 0.35
        ramp.color_ramp.elements[0].color = _rgba(c2)
        ramp.color_ramp.elements[1].position = 0.65
        ramp.color_ramp.elements[1].color = _rgba(c1)
        nt.links.new(n.outputs["Fac"], ramp.inputs["Fac"])
        summary["colors"] = [[round(x, 3) for x in c1], [round(x, 3) for x in c2]]
        return _finish(m, nt, out, ramp.outputs["Color"], rnd, False, summary)
    raise ValueError(kind)
