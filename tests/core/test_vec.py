"""engine/core/vec.py: the triangle tables as rows give the (T, 3) formulas' values bit for bit."""
import numpy as np

from engine.core.vec import cross, cross_rows, norm, triangle_rows, triangle_rows_chunks


def random_mesh(seed=5, n_vertices=4000, n_triangles=9000):
    rng = np.random.default_rng(seed)
    vertices = rng.normal(size=(n_vertices, 3)) * 10.0 ** rng.integers(-6, 6, size=(n_vertices, 1))
    triangles = rng.integers(0, n_vertices, size=(n_triangles, 3))
    triangles[:5] = [7, 7, 8]                      # degenerate: two corners the same vertex
    return vertices, triangles


def test_triangle_rows_are_the_corner_formulas_bit_for_bit():
    vertices, triangles = random_mesh()
    v = vertices[triangles]
    v0, e1, e2, scale = triangle_rows(vertices, triangles)
    for got, want in ((v0, v[:, 0]), (e1, v[:, 1] - v[:, 0]), (e2, v[:, 2] - v[:, 0])):
        assert got.shape == (3, len(triangles)) and got.flags.c_contiguous
        assert np.array_equal(got, want.T)
    assert np.array_equal(scale, np.abs(v).max(axis=(1, 2)))
    assert np.array_equal(cross(e1, e2), np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]).T)
    assert np.array_equal(cross_rows(e1, e2), cross(e1, e2)) and cross_rows(e1, e2).flags.c_contiguous
    assert np.array_equal(norm(cross(e1, e2)),
                          np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1))
    # control: another order of the same sum is not the same bits on this data (the check can fail)
    c = cross(e1, e2)
    assert not np.array_equal(np.sqrt(c[0] * c[0] + (c[1] * c[1] + c[2] * c[2])), norm(c))


def test_triangle_rows_of_no_triangles():
    v0, e1, e2, scale = triangle_rows(np.zeros((0, 3)), np.zeros((0, 3), np.int64))
    assert v0.shape == e1.shape == e2.shape == (3, 0) and scale.shape == (0,)


def test_triangle_rows_in_pieces_are_the_whole_rows():
    vertices, triangles = random_mesh()
    whole = triangle_rows(vertices, triangles)
    for size in (1000, 4096, 9000, 20000):
        pieces = list(triangle_rows_chunks(vertices, triangles, size))
        assert [start for start, _ in pieces] == list(range(0, len(triangles), size))
        for k, want in enumerate(whole):
            got = np.concatenate([rows[k] for _, rows in pieces], axis=-1)
            assert got.shape == want.shape and np.array_equal(got, want)
    assert list(triangle_rows_chunks(vertices, triangles[:0])) == []
    # control: pieces that started one triangle late would not be the whole rows
    late = np.concatenate([rows[1] for _, rows in triangle_rows_chunks(vertices, triangles[1:], 4096)], axis=-1)
    assert not np.array_equal(late, whole[1][:, :-1])
