"""Meshes and what is done to them: I/O, RBF warps, projection onto surfaces, surface interpolation."""

from .mesh import Mesh, SeamSplit
from .meshio import MESH_SUFFIXES, read_mesh, write_mesh
from .project import Projection, closest_point_on_triangles, project_points
from .rbf import KERNELS, RbfWarp, apply_operator, rbf_operator_from_distances
from .surface import BiharmonicInterpolation, SurfaceRbf, cotangent_laplacian, edge_graph, geodesic_distances
from .topology import boundary_loops, component_labels

__all__ = ["KERNELS", "MESH_SUFFIXES", "BiharmonicInterpolation", "Mesh", "Projection", "RbfWarp", "SeamSplit",
           "SurfaceRbf", "apply_operator", "boundary_loops", "component_labels", "closest_point_on_triangles",
           "cotangent_laplacian", "edge_graph", "geodesic_distances", "project_points",
           "rbf_operator_from_distances", "read_mesh", "write_mesh"]
