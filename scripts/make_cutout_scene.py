#!/usr/bin/env python3
"""Writes scenes/cutout.gltf: the project's own scene for the glTF material inputs of real assets
(WHITTED-materials.md): a MASK lattice fence that a spot light shines through, a BLEND pane tinted
by COLOR_0 (alpha 0.3 to 0.7), a normal-mapped back wall without TANGENT (MikkTSpace tangents), a
floor whose texture goes through KHR_texture_transform, and a sign with an emissive texture and
KHR_materials_emissive_strength. Standard library only; textures are PNG data URIs.

    python3 scripts/make_cutout_scene.py   # from the repository root
"""
import base64
import json
import math
import struct
import zlib


def png(width, height, pixel, channels):
    """An 8-bit PNG (RGB or RGBA) whose pixel (x, y) is pixel(x, y), top row first."""
    rows = b""
    for y in range(height):
        rows += b"\0" + bytes(v for x in range(width) for v in pixel(x, y))
    color_type = 6 if channels == 4 else 2

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, 8, color_type, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows, 9))
            + chunk(b"IEND", b""))


def data_uri(mime, data):
    return f"data:{mime};base64," + base64.b64encode(data).decode()


# Textures.
def lattice(x, y):
    # 64x64, bars 6 texels wide every 16: opaque wood, holes with alpha 0.
    bar = (x % 16) < 6 or (y % 16) < 6
    return (150, 105, 60, 255) if bar else (150, 105, 60, 0)


def checker(x, y):
    return (200, 200, 190) if ((x // 8) + (y // 8)) % 2 == 0 else (70, 90, 120)


def bumps(x, y):
    # Tangent-space normals of a field of round bumps, 8 per side of a 64x64 tile.
    cx, cy = (x % 8) - 3.5, (y % 8) - 3.5
    r2 = (cx * cx + cy * cy) / 12.25
    if r2 >= 1.0:
        n = (0.0, 0.0, 1.0)
    else:
        # +X is +u, +Y is image up (decreasing v): a bump's right side leans to +X, its top to +Y.
        h = math.sqrt(1.0 - r2)
        n = (cx / 3.5 * 0.8, -cy / 3.5 * 0.8, h + 0.2)
    length = math.sqrt(sum(c * c for c in n))
    return tuple(round((c / length * 0.5 + 0.5) * 255) for c in n)


def glow(x, y):
    # A soft ring: emission up to 0.7 of the factor.
    d = math.hypot(x - 15.5, y - 15.5) / 16.0
    v = max(0.0, 1.0 - abs(d - 0.6) * 3.0) * 0.7
    c = round(v ** (1 / 2.2) * 255)
    return (c, c, c)


images = [
    data_uri("image/png", png(64, 64, lattice, 4)),
    data_uri("image/png", png(32, 32, checker, 3)),
    data_uri("image/png", png(64, 64, bumps, 3)),
    data_uri("image/png", png(32, 32, glow, 3)),
]

# Geometry: quads as two triangles, each with positions, normals, uvs (and colours).
buffer = bytearray()
views, accessors, meshes = [], [], []


def add(values, fmt_count, kind, with_bounds=False):
    offset = len(buffer)
    flat = [v for item in values for v in item]
    buffer.extend(struct.pack(f"<{len(flat)}f", *flat))
    views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(flat) * 4})
    a = {"bufferView": len(views) - 1, "componentType": 5126, "count": len(values), "type": kind}
    if with_bounds:
        a["min"] = [min(v[i] for v in values) for i in range(fmt_count)]
        a["max"] = [max(v[i] for v in values) for i in range(fmt_count)]
    accessors.append(a)
    return len(accessors) - 1


def add_indices(indices):
    offset = len(buffer)
    buffer.extend(struct.pack(f"<{len(indices)}I", *indices))
    views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(indices) * 4})
    accessors.append({"bufferView": len(views) - 1, "componentType": 5125, "count": len(indices),
                      "type": "SCALAR"})
    return len(accessors) - 1


def quad(corners, normal, uvs, material, colors=None):
    """A quad from four corners in counter-clockwise order seen from its front."""
    attributes = {
        "POSITION": add(corners, 3, "VEC3", True),
        "NORMAL": add([normal] * 4, 3, "VEC3"),
        "TEXCOORD_0": add(uvs, 2, "VEC2"),
    }
    if colors:
        attributes["COLOR_0"] = add(colors, 4, "VEC4")
    meshes.append({"primitives": [{"attributes": attributes, "indices": add_indices([0, 1, 2, 0, 2, 3]),
                                   "material": material}]})
    return len(meshes) - 1


uv_quad = [(0, 1), (1, 1), (1, 0), (0, 0)]
floor = quad([(-5, 0, 4), (5, 0, 4), (5, 0, -4), (-5, 0, -4)], (0, 1, 0),
             [(0, 1), (4, 1), (4, 0), (0, 0)], 0)
wall = quad([(-5, 0, -2.5), (5, 0, -2.5), (5, 4, -2.5), (-5, 4, -2.5)], (0, 0, 1),
            [(0, 2), (5, 2), (5, 0), (0, 0)], 1)
fence = quad([(-2.2, 0, 0), (0.6, 0, 0), (0.6, 1.6, 0), (-2.2, 1.6, 0)], (0, 0, 1),
             [(0, 1), (2.5, 1), (2.5, 0), (0, 0)], 2)
pane = quad([(0.9, 0.1, 1.2), (2.3, 0.1, 0.9), (2.3, 1.5, 0.9), (0.9, 1.5, 1.2)],
            (0.2095, 0, 0.9778), uv_quad, 3,
            colors=[(0.6, 0.8, 1.0, 0.3), (0.6, 0.8, 1.0, 0.7), (0.6, 0.8, 1.0, 0.7),
                    (0.6, 0.8, 1.0, 0.3)])
sign = quad([(1.2, 2.2, -2.45), (2.6, 2.2, -2.45), (2.6, 3.6, -2.45), (1.2, 3.6, -2.45)],
            (0, 0, 1), uv_quad, 4)

materials = [
    {"name": "floor", "pbrMetallicRoughness": {
        "baseColorTexture": {"index": 1, "extensions": {"KHR_texture_transform": {
            "offset": [0.1, 0.2], "rotation": 0.4, "scale": [1.5, 0.8]}}},
        "metallicFactor": 0.0, "roughnessFactor": 0.8}},
    {"name": "bumpy wall", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.6, 0.5, 1.0],
                                                    "metallicFactor": 0.0, "roughnessFactor": 0.5},
     "normalTexture": {"index": 2, "scale": 1.0}},
    {"name": "lattice fence", "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": True,
     "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0,
                              "roughnessFactor": 0.7}},
    {"name": "tinted pane", "alphaMode": "BLEND", "doubleSided": True,
     "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0,
                              "roughnessFactor": 0.2}},
    {"name": "glowing sign", "pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.1, 0.1, 1.0],
                                                      "metallicFactor": 0.0, "roughnessFactor": 0.9},
     "emissiveFactor": [0.4, 0.8, 0.6], "emissiveTexture": {"index": 3},
     "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 1.6}}},
]


def look_at_rotation(pitch):
    """A quaternion (x, y, z, w) turning about +X by pitch radians."""
    return [math.sin(pitch / 2), 0.0, 0.0, math.cos(pitch / 2)]


spot_pitch = -math.atan2(2.4, 3.5)
gltf = {
    "asset": {"version": "2.0", "generator": "stereotrace scripts/make_cutout_scene.py"},
    "extensionsUsed": ["KHR_lights_punctual", "KHR_texture_transform",
                       "KHR_materials_emissive_strength"],
    "extensions": {"KHR_lights_punctual": {"lights": [
        {"name": "spot", "type": "spot", "color": [1.0, 0.95, 0.85], "intensity": 22.0,
         "spot": {"innerConeAngle": 0.35, "outerConeAngle": 0.6}},
        {"name": "fill", "type": "point", "color": [0.8, 0.85, 1.0], "intensity": 6.0},
    ]}},
    "scene": 0,
    "scenes": [{"nodes": list(range(8))}],
    "nodes": [
        {"name": "floor", "mesh": floor},
        {"name": "bumpy wall", "mesh": wall},
        {"name": "lattice fence", "mesh": fence},
        {"name": "tinted pane", "mesh": pane},
        {"name": "glowing sign", "mesh": sign},
        {"name": "Camera", "camera": 0, "translation": [0.0, 1.6, 5.5],
         "rotation": look_at_rotation(-0.16)},
        {"name": "spot", "translation": [-0.8, 2.4, 3.5], "rotation": look_at_rotation(spot_pitch),
         "extensions": {"KHR_lights_punctual": {"light": 0}}},
        {"name": "fill", "translation": [3.0, 3.0, 3.0],
         "extensions": {"KHR_lights_punctual": {"light": 1}}},
    ],
    "cameras": [{"type": "perspective", "perspective": {"yfov": 0.75, "znear": 0.05,
                                                        "aspectRatio": 16 / 9}}],
    "meshes": meshes,
    "materials": materials,
    "images": [{"uri": u} for u in images],
    "samplers": [{"magFilter": 9729, "minFilter": 9729, "wrapS": 10497, "wrapT": 10497},
                 {"magFilter": 9728, "minFilter": 9728, "wrapS": 10497, "wrapT": 10497}],
    "textures": [{"source": 0, "sampler": 1}, {"source": 1, "sampler": 1},
                 {"source": 2, "sampler": 0}, {"source": 3, "sampler": 0}],
    "accessors": accessors,
    "bufferViews": views,
    "buffers": [{"byteLength": len(buffer),
                 "uri": data_uri("application/octet-stream", bytes(buffer))}],
}
with open("scenes/cutout.gltf", "w") as f:
    json.dump(gltf, f, indent=1)
    f.write("\n")
