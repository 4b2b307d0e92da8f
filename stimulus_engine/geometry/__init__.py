"""Mesh and image-plane basics every other part of the engine builds on: OBJ files, mesh I/O,
mesh operations, exact closest points, UV rasterisation, bilinear sampling, 2-D polylines and
the ICT topology's vertex sets. Imports nothing of the engine but its shipped ``data``.

Public API
----------
load_mesh, save_mesh, load_parts, select_region, mesh_uv_layout, texture_image
    Meshes with their UV layout and texture (OBJ/MTL, PLY, glTF through trimesh; module
    ``mesh_io``, the OBJ text format itself in ``obj_format``).
face_normals, vertex_normals, boundary_loops, vertex_adjacency, grow_rings
    Mesh operations on plain arrays (module ``mesh_ops``; bit-identical to trimesh's where it
    has them).
SurfaceIndex
    Exact closest points on a triangle mesh (a bounding-volume hierarchy, compiled with Numba
    where installed; module ``closest``, the tree in ``triangle_bvh``).
rasterize_uv
    The texels a UV layout's triangles cover, with barycentric weights (module ``uv_raster``).
sample_bilinear, sample_points
    Bilinear image sampling (module ``sampling``).
catmull_rom, inside_polygon, closest_on_polygon
    2-D polylines for cut lines and contours (module ``polyline2d``).
ICT_GEOMETRY_RANGES, ict_regions
    Named vertex sets of the ICT Face Model topology (module ``ict_topology``).
rotation_onto
    The smallest rotation taking one direction onto another (module ``rotation``).
smoothstep
    A smooth 0-to-1 ramp for fading weights (module ``ramps``).
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["closest", "ict_topology", "mesh_io", "mesh_ops", "obj_format", "polyline2d", "ramps",
                "rotation", "sampling", "triangle_bvh", "uv_raster"],
    submod_attrs={
        "closest": ["SurfaceIndex"],
        "ict_topology": ["ICT_GEOMETRY_RANGES", "ict_regions"],
        "mesh_io": ["load_mesh", "load_parts", "mesh_uv_layout", "save_mesh", "select_region", "texture_image"],
        "mesh_ops": ["boundary_loops", "face_normals", "grow_rings", "vertex_adjacency", "vertex_normals"],
        "polyline2d": ["catmull_rom", "closest_on_polygon", "inside_polygon"],
        "ramps": ["smoothstep"],
        "rotation": ["rotation_onto"],
        "sampling": ["sample_bilinear", "sample_points"],
        "uv_raster": ["rasterize_uv"],
    },
)

__all__ = [
    "ICT_GEOMETRY_RANGES",
    "SurfaceIndex",
    "boundary_loops",
    "catmull_rom",
    "closest_on_polygon",
    "face_normals",
    "grow_rings",
    "ict_regions",
    "inside_polygon",
    "load_mesh",
    "load_parts",
    "mesh_uv_layout",
    "rasterize_uv",
    "rotation_onto",
    "sample_bilinear",
    "sample_points",
    "save_mesh",
    "select_region",
    "smoothstep",
    "texture_image",
    "vertex_adjacency",
    "vertex_normals",
]
