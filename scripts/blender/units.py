"""Conversions between Blender/Cycles and PropCam: axes, light units, panoramas.

Axes: ours (x, y, z) = Blender (x, z, -y); ours is Y up, Blender Z up, both
metres and right-handed. Our lights are scene-referred linear radiance
(area, disc, sphere, spot with a radius), intensity in W/sr (point, spot of
radius 0), irradiance (sun) or a radiance map (ibl). The light-unit
conversions below are the ones scripts/blender_units_check.sh measures
(docs/blender_world.md): the generator and the check use these same functions.
No Blender import here: usable from plain Python.
"""
import math

import numpy as np

# ours -> Blender: B = C @ ours
C = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def to_blender(p):
    x, y, z = (float(v) for v in p)
    return (x, -z, y)


def from_blender(p):
    x, y, z = (float(v) for v in p)
    return (x, z, -y)


def matrix_to_blender(m4_ours):
    """A 4x4 transform acting on our coordinates -> the same transform acting on Blender's."""
    c4 = np.eye(4)
    c4[:3, :3] = C
    return c4 @ np.asarray(m4_ours, float) @ c4.T


def normals_from_blender(n):
    """H x W x 3 Blender-world normals -> ours."""
    return np.stack([n[..., 0], n[..., 2], -n[..., 1]], axis=-1)


# --- cameras -----------------------------------------------------------------
def camera_rotation(yaw_deg, pitch_deg, roll_deg):
    """R_world_from_cam (ours; columns = camera x right, y down, z forward).
    yaw 0 looks along -Z, positive yaw turns toward -X (counter-clockwise from
    above); positive pitch looks up; positive roll turns the image clockwise."""
    def rx(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])

    def ry(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])

    def rz(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])

    r0 = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])
    return ry(math.radians(yaw_deg)) @ rx(math.radians(pitch_deg)) @ r0 @ rz(math.radians(roll_deg))


def blender_camera_matrix(R_world_from_cam, center):
    """4x4 Blender matrix_world of a camera (local X right, Y up, looking along -Z)."""
    R = np.asarray(R_world_from_cam, float)
    local = np.stack([R[:, 0], -R[:, 1], -R[:, 2]], axis=1)  # ours
    m = np.eye(4)
    m[:3, :3] = C @ local
    m[:3, 3] = to_blender(center)
    return m


def blender_lens_mm(fx_px, width_px, sensor_width_mm=36.0):
    """Focal length for sensor_fit HORIZONTAL: fx = lens / sensor_width * W."""
    return fx_px * sensor_width_mm / width_px


def project(K, R_world_from_cam, center, p):
    """Our pinhole projection: (u, v, depth along z). Pixel (0,0) = centre of the top-left pixel."""
    pc = np.asarray(R_world_from_cam, float).T @ (np.asarray(p, float) - np.asarray(center, float))
    return K["fx"] * pc[0] / pc[2] + K["cx"], K["fy"] * pc[1] / pc[2] + K["cy"], pc[2]


# --- lights ------------------------------------------------------------------
def mesh_emission_radiance(color, strength):
    """Emission shader on a mesh (one side, see bcommon.emission_material):
    radiance = strength * colour."""
    return [float(c) * strength for c in color]


def area_light_radiance(color, power_w, area_m2):
    """Blender area light object (power P W over area A): radiance = colour * P / (4 A)."""
    return [float(c) * power_w / (4.0 * area_m2) for c in color]


def area_light_power(radiance_lum, area_m2):
    """Inverse of area_light_radiance for a white light."""
    return radiance_lum * 4.0 * area_m2


def point_light_sphere_radiance(color, power_w, radius_m):
    """Blender point light (power P W, soft radius r): intensity colour*P/(4 pi)
    W/sr, emitted by a disc of radius r facing the shading point ~ our sphere of
    radius r with radiance I / (pi r^2)."""
    return [float(c) * power_w / (4.0 * math.pi) / (math.pi * radius_m ** 2) for c in color]


def point_light_intensity(color, power_w):
    """Blender point light of soft radius 0 (power P W): our `point` light of
    intensity colour*P/(4 pi) W/sr (Cycles 3.4 gives a radius-0 light the
    emission P/(4 pi) per steradian, so a surface at d facing it receives
    I/d^2)."""
    return [float(c) * power_w / (4.0 * math.pi) for c in color]


def spot_light(color, power_w, radius_m, spot_size_rad, spot_blend):
    """Blender spot light (power P W, soft radius r, spot_size = the cone's
    full angle, spot_blend) -> the fields of our `spot` light. Its intensity
    is the point light's: radiance colour*P/(4 pi)/(pi r^2) for r > 0 (our
    sphere, as point_light_sphere_radiance), intensity colour*P/(4 pi) W/sr
    for r = 0. The cone is Cycles 3.4's on both sides: cos(theta) times a
    smoothstep over the band spot_blend*(1 - cos(spot_size/2)) of cosines
    inside the edge (render/include/propcam/render/lights.h SpotCone)."""
    intensity = (point_light_sphere_radiance(color, power_w, radius_m) if radius_m > 0
                 else point_light_intensity(color, power_w))
    return {"type": "spot", "radius": float(radius_m), "cone_angle_deg": math.degrees(spot_size_rad),
            "blend": float(spot_blend), "intensity": intensity}


def disc_light_radiance(color, power_w, radius_m):
    """Blender area light of shape DISK (size = its diameter 2r, power P W):
    our one-sided `disc` of radius r and radiance colour*P/(4 pi r^2), the
    area light's rule with A = pi r^2."""
    return area_light_radiance(color, power_w, math.pi * radius_m ** 2)


def area_rotation_deg(normal_ours, axis_u_ours):
    """The `rotation_deg` of our `area` light whose width runs along axis_u
    (projected into the light's plane): the angle from our default width axis
    (Y x normal, or +X for a vertical normal) about the normal, right-handed
    (counter-clockwise seen from the lit side)."""
    n = np.asarray(normal_ours, float)
    n /= np.linalg.norm(n)
    t = np.cross([0.0, 1.0, 0.0], n)
    t = t / np.linalg.norm(t) if np.linalg.norm(t) > 1e-9 else np.array([1.0, 0.0, 0.0])
    u = np.asarray(axis_u_ours, float)
    u = u - n * (u @ n)
    return math.degrees(math.atan2(np.cross(t, u) @ n, t @ u))


def sun_irradiance(color, strength):
    """Blender sun: strength = irradiance (W/m^2) on a surface facing it."""
    return [float(c) * strength for c in color]


def sun_angle_radius_deg(blender_angle_rad):
    """Blender's sun `angle` is the disc's angular diameter; ours is the radius."""
    return math.degrees(blender_angle_rad) / 2.0


def uv_sphere_effective_radius(radius, segments, rings):
    """Radius of the sphere with the area of Blender's UV sphere (flat quads)."""
    area = 0.0
    dphi = 2.0 * math.pi / segments
    for i in range(rings):
        t0, t1 = math.pi * i / rings, math.pi * (i + 1) / rings
        r0, r1 = radius * math.sin(t0), radius * math.sin(t1)
        z0, z1 = radius * math.cos(t0), radius * math.cos(t1)
        # a ring of trapezoids (triangles at the poles)
        a, b = 2 * r0 * math.sin(dphi / 2), 2 * r1 * math.sin(dphi / 2)
        dr = (r1 - r0) * math.cos(dphi / 2)
        slant = math.hypot(dr, z1 - z0)
        area += segments * 0.5 * (a + b) * slant
    return math.sqrt(area / (4.0 * math.pi))


def sphere_power(radiance, radius):
    """Power of a Lambertian sphere of uniform radiance L: pi L x 4 pi r^2."""
    return [4.0 * math.pi ** 2 * radius ** 2 * float(c) for c in radiance]


def lampshade_emission(bulb_radiance, bulb_radius, d_top, d_bottom, r_top, r_bottom, slant_area,
                       transmittance, reflectance):
    """A bulb inside a lampshade (a frustum with open ends), replaced by what
    leaves it: the shade's outside glowing with the light it transmits, and two
    discs closing the openings with the light that leaves through them.

    The bulb (a sphere of `bulb_radiance`, radius `bulb_radius`, power Phi)
    sends the fraction (1 - cos theta) / 2 of Phi straight through each
    opening (theta: the opening's half-angle seen from the bulb's centre,
    d_top/d_bottom its distance from the opening's plane); the rest hits the
    shade. The shade transmits `transmittance`, reflects `reflectance` (per
    channel, diffuse); reflected light leaves the cavity through the openings
    with the probability q = A_open / (A_open + A_shade) at each bounce (a
    cavity of uniform radiosity) and meets the shade again otherwise. Returns
    Lambertian radiances {"top", "bottom", "shade"} (per channel) of equal
    power, and the power budget."""
    phi = np.asarray(sphere_power(bulb_radiance, bulb_radius))
    f_top = 0.5 * (1.0 - d_top / math.hypot(d_top, r_top))
    f_bot = 0.5 * (1.0 - d_bottom / math.hypot(d_bottom, r_bottom))
    a_top, a_bot = math.pi * r_top ** 2, math.pi * r_bottom ** 2
    q = (a_top + a_bot) / (a_top + a_bot + slant_area)
    T = np.asarray(transmittance, float)
    rho = np.asarray(reflectance, float)
    hits = phi * (1.0 - f_top - f_bot) / (1.0 - rho * (1.0 - q))  # all arrivals on the shade
    through_shade = T * hits
    reflected_out = rho * q * hits
    top = phi * f_top + reflected_out * a_top / (a_top + a_bot)
    bot = phi * f_bot + reflected_out * a_bot / (a_top + a_bot)
    return {"top": (top / (math.pi * a_top)).tolist(), "bottom": (bot / (math.pi * a_bot)).tolist(),
            "shade": (through_shade / (math.pi * slant_area)).tolist(),
            "budget": {"bulb_power": phi.tolist(), "direct_fraction_top": f_top, "direct_fraction_bottom": f_bot,
                       "cavity_escape_q": q, "power_top": top.tolist(), "power_bottom": bot.tolist(),
                       "power_shade": through_shade.tolist()}}


def frustum_slant_area(r_bottom, r_top, height):
    return math.pi * (r_bottom + r_top) * math.hypot(r_bottom - r_top, height)


# --- colours -----------------------------------------------------------------
def _g(lam, mu, s1, s2):
    s = np.where(lam < mu, s1, s2)
    return np.exp(-0.5 * ((lam - mu) / s) ** 2)


def blackbody_rgb(kelvin):
    """Linear Rec.709 colour of a black body, luminance 1 (CIE 1931 observer by
    the multi-lobe Gaussian fit of Wyman, Sloan and Shirley 2013)."""
    lam = np.arange(380.0, 781.0, 1.0)
    xb = 1.056 * _g(lam, 599.8, 37.9, 31.0) + 0.362 * _g(lam, 442.0, 16.0, 26.7) - 0.065 * _g(lam, 501.1, 20.4, 26.2)
    yb = 0.821 * _g(lam, 568.8, 46.9, 40.5) + 0.286 * _g(lam, 530.9, 16.3, 31.1)
    zb = 1.217 * _g(lam, 437.0, 11.8, 36.0) + 0.681 * _g(lam, 459.0, 26.0, 13.8)
    l_m = lam * 1e-9
    planck = 1.0 / (l_m ** 5 * (np.exp(1.4387769e-2 / (l_m * kelvin)) - 1.0))
    X, Y, Z = (float(np.sum(planck * c)) for c in (xb, yb, zb))
    m = np.array([[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]])
    rgb = np.clip(m @ np.array([X, Y, Z]) / Y, 1e-4, None)
    lum = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
    return [float(c) for c in rgb / lum]


def luminance(rgb):
    rgb = np.asarray(rgb, float)
    return 0.2126 * rgb[..., 0] + 0.7152 * rgb[..., 1] + 0.0722 * rgb[..., 2]


# --- panoramas ---------------------------------------------------------------
# Our equirectangular convention (render/src/lights.cpp direction_to_uv):
# u = (atan2(x, -z) + pi) / 2pi, v = acos(y) / pi: row 0 is +Y, the CENTRE
# column looks along -Z, u = 3/4 along +X, the edges along +Z.
def our_uv_to_direction(u, v):
    phi = u * 2.0 * math.pi - math.pi
    th = v * math.pi
    s = math.sin(th)
    return np.array([s * math.sin(phi), math.cos(th), -s * math.cos(phi)])


def our_direction_to_uv(d):
    d = np.asarray(d, float) / np.linalg.norm(d)
    u = (math.atan2(d[0], -d[2]) + math.pi) / (2.0 * math.pi)
    return u % 1.0, math.acos(max(-1.0, min(1.0, d[1]))) / math.pi


# A Cycles equirectangular camera with rotation_euler (90 deg, 0, 0) (default
# latitude/longitude ranges), its image flipped left-right and rolled by half
# its width, is in our convention (measured: coloured markers at +-X, +Y, -Z).
PANO_CAMERA_EULER_DEG = (90.0, 0.0, 0.0)


def pano_to_ours(img_top_down):
    a = img_top_down[:, ::-1]
    return np.roll(a, a.shape[1] // 2, axis=1)


# Blender's Environment Texture (equirectangular) reads texel u_b for a
# direction where ours reads u_b + 1/4: a Mapping node rotating the lookup by
# this angle about Blender Z makes Blender read our maps our way.
ENV_MAPPING_Z_DEG = -90.0


def texel_solid_angles(h, w):
    th = (np.arange(h) + 0.5) / h * math.pi
    return (2.0 * math.pi / w) * (math.pi / h) * np.sin(th)[:, None] * np.ones((1, w))


def add_sun_to_pano(pano, direction_ours, irradiance_rgb):
    """Adds a sun of irradiance E (on a surface facing it) to an equirectangular
    map in our convention as one bilinear splat: the texels' solid-angle-weighted
    sum is E."""
    h, w = pano.shape[:2]
    u, v = our_direction_to_uv(direction_ours)
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = math.floor(x), math.floor(y)
    fx, fy = x - x0, y - y0
    om = texel_solid_angles(h, w)
    for dx, dy, wt in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
        yy = min(max(y0 + dy, 0), h - 1)
        xx = (x0 + dx) % w
        pano[yy, xx, :3] += wt * np.asarray(irradiance_rgb, float) / om[yy, xx]
    return pano
