"""The admissible displacements of Eq. (3) as the model document reads them."""

import numpy as np

from trackjam.world.moves import admissible_moves, displacement_set


def test_paper_default_gives_the_79_controls_of_table_1():
    D = displacement_set([1, 3, 5], 8, 8)
    assert len(D) == 79


def test_configurations_1_to_4_give_the_11_controls_of_table_1():
    D = displacement_set([3], 4, 8)
    assert len(D) == 11
    norms = np.linalg.norm(D, axis=1)
    assert np.count_nonzero(norms == 0) == 1  # hover
    assert np.count_nonzero(np.isclose(D[:, 2], 3)) == 1  # up
    assert np.count_nonzero(np.isclose(D[:, 2], -3)) == 1  # down
    assert np.count_nonzero(np.isclose(D[:, 2], 0) & np.isclose(norms, 3)) == 8  # horizontal


def test_literal_reading_with_finer_inclination_gives_175():
    assert len(displacement_set([1, 3, 5], 16, 8)) == 175


def test_hover_is_control_zero_and_all_vectors_are_distinct_with_the_right_lengths():
    D = displacement_set([1, 3, 5], 8, 8)
    assert np.all(D[0] == 0)
    assert len(np.unique(np.round(D, 9), axis=0)) == len(D)
    assert set(np.round(np.linalg.norm(D[1:], axis=1), 9)) == {1.0, 3.0, 5.0}


def test_moves_leaving_the_area_are_inadmissible():
    D = displacement_set([1, 3, 5], 8, 8)
    at_corner = admissible_moves([0, 0, 0], D, [0, 0, 0], [100, 100, 100])
    assert at_corner[0]
    assert np.all(np.all(D[at_corner] >= -1e-9, axis=1))
    assert not np.all(at_corner)
    assert np.all(admissible_moves([50, 50, 50], D, [0, 0, 0], [100, 100, 100]))
    near_top = admissible_moves([50, 50, 98], D, [0, 0, 0], [100, 100, 100])
    assert np.all(D[near_top][:, 2] <= 2 + 1e-9) and np.any(D[~near_top][:, 2] > 2)
