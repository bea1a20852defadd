"""Surface meshes of simple tools for the tests: a ball's polygon (2D) or
polyhedron (3D), and meshio files of them."""
import numpy as np


def ball_polygon(center, radius, segments):
    """(points, segments) of a regular polygon inscribed in the circle,
    counter-clockwise (the tool on the left of each segment)."""
    angle = 2.0 * np.pi * (np.arange(segments) + 0.5) / segments
    points = np.asarray(center, float) + radius * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    return points, np.stack([np.arange(segments), (np.arange(segments) + 1) % segments], axis=1)


def ball_polyhedron(center, radius, level):
    """(points, triangles) of an octahedron subdivided ``level`` times and
    projected on the sphere, every triangle's normal (b - a) x (c - a)
    pointing out."""
    points = [np.array(p, float) for p in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))]
    triangles = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    for _ in range(level):
        middle, finer = {}, []

        def mid(i, j):
            key = (min(i, j), max(i, j))
            if key not in middle:
                m = points[i] + points[j]
                points.append(m / np.linalg.norm(m))
                middle[key] = len(points) - 1
            return middle[key]
        for a, b, c in triangles:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            finer += [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
        triangles = finer
    points = np.array(points)
    triangles = np.array(triangles)
    corners = points[triangles]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    inward = np.einsum("ij,ij->i", normal, corners.mean(axis=1)) < 0.0
    triangles[inward] = triangles[inward][:, ::-1]
    return np.asarray(center, float) + radius * points, triangles


def write_surface(path, points, facets):
    """A VTK file of the surface (lines in 2D, triangles in 3D)."""
    import meshio
    padded = np.zeros((len(points), 3))
    padded[:, :points.shape[1]] = points
    meshio.write_points_cells(path, padded, [("line" if facets.shape[1] == 2 else "triangle", facets)])
