"""The paper's GRASP: never better than the optimum, reaches it on tiny instances, always
feasible when the constraints are on, and its compiled search follows its numpy reference."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.control.exact import solve_exact
from trackjam.control.grasp import (
    _sample_block,
    kernel_local_neighbourhood,
    local_neighbourhood_reference,
    neighbour_lists,
    solve_grasp,
)
from trackjam.control.objective import evaluate

from control_instances import (
    assert_grasp_kernel_follows_its_twin,
    random_problem,
    small_displacements,
    tiny_displacements,
)


def rngs(seed, n):
    return [np.random.default_rng([seed, j]) for j in range(n)]


def test_kernel_follows_numpy_reference(antenna):
    rng = np.random.default_rng(5)
    for trial in range(4):
        P = random_problem(rng, antenna, 3, 1 + trial % 3, constraints=trial % 2 == 0)
        assert_grasp_kernel_follows_its_twin(P, trial, 200, 15)


def test_kernel_follows_numpy_reference_when_samples_tie(antenna):
    """p_D rounded to 0 or 1/2: Xi takes a handful of values, so most joint samples tie with the
    iteration's best. The compiled search keeps the first of equal samples (strict `>`), as the
    twin's argmax does; a `>=` in the sampling loop keeps the last and picks another plan. Both
    loops: the hot one (one objective sample) and the general one (two belief samples with the
    same table, whose weighted mean 0.5 v + 0.5 v is v exactly, so the ties stay exact)."""
    from dataclasses import replace

    rng = np.random.default_rng(21)
    for trial in range(4):
        P = random_problem(rng, antenna, 3, 1 + trial % 2, constraints=trial % 2 == 0, spread=6.0)
        P = replace(P, p_d=np.where(P.p_d > 0, 0.5, 0.0))
        assert 0 < (P.p_d > 0).mean() < 1
        assert_grasp_kernel_follows_its_twin(P, trial, 200, 5)
        two = replace(P, samples=np.stack([P.aim, P.aim]), weights=np.array([0.5, 0.5]),
                      p_d_samples=np.stack([P.p_d, P.p_d]))
        assert_grasp_kernel_follows_its_twin(two, trial, 200, 5)


def test_neighbours_are_the_nearest_other_displacements(antenna):
    P = random_problem(np.random.default_rng(0), antenna)
    neigh, n_neigh = neighbour_lists(P, 6)
    D = P.displacements[P.move[0, : P.n_cand[0]]]
    for c in range(P.n_cand[0]):
        d = np.linalg.norm(D - D[c], axis=1)
        chosen = d[neigh[0, c, : n_neigh[0, c]]]
        assert c not in neigh[0, c, : n_neigh[0, c]]
        others = np.delete(d, np.r_[c, neigh[0, c, : n_neigh[0, c]]])
        assert chosen.max() <= others.min() + 1e-12


def test_local_neighbourhood_draws_two_distinct_neighbours_like_its_twin():
    # every neighbour count the search meets: none, one, two, several (u-, u+ differ when >= 2)
    rng = np.random.default_rng(3)
    L = 4
    for trial in range(300):
        n_neigh = rng.integers(0, 6, size=(2, 5))
        neigh = rng.permutation(np.arange(5 * 2 * 5)).reshape(2, 5, 5)
        me, u, l0 = trial % 2, int(rng.integers(5)), int(rng.integers(L))
        r1, r2 = np.random.default_rng(trial), np.random.default_rng(trial)
        u_minus, u_plus, l_minus, l_plus = kernel_local_neighbourhood(r1, neigh, n_neigh, me, u, l0, L)
        us, ls = local_neighbourhood_reference(r2, neigh, n_neigh, me, u, l0, L)
        assert [u_minus, u, u_plus] == us and [l_minus, l0, l_plus] == ls
        assert r1.random() == r2.random()  # both drew as many numbers
        m = n_neigh[me, u]
        near = set(neigh[me, u, :m])
        if m >= 2:
            assert u_minus != u_plus and {u_minus, u_plus} <= near
        else:
            assert u_minus == u_plus == (neigh[me, u, 0] if m == 1 else u)
        assert ls == [max(l0 - 1, 0), l0, min(l0 + 1, L - 1)]


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 3), st.booleans())
def test_grasp_is_feasible_and_never_beats_exact(antenna, seed, at_least, constraints):
    rng = np.random.default_rng(seed)
    P = random_problem(rng, antenna, 3, at_least, constraints, spread=rng.uniform(3, 20))
    g = solve_grasp(P, rngs(seed, 3), samples=200, iterations=5)
    e = solve_exact(P)
    assert g.objective <= e.objective + 1e-12
    if constraints:
        assert g.feasible
    xi, ok = evaluate(P, [np.flatnonzero(P.move[i] == g.move[i])[0] for i in range(3)], g.level)
    assert np.isclose(xi, g.objective) and ok == g.feasible


def test_grasp_reaches_the_optimum_on_tiny_instances(antenna):
    rng = np.random.default_rng(11)
    for trial in range(6):
        P = random_problem(rng, antenna, 2 + trial % 2, 1 + trial % 2, trial % 3 != 0,
                           displacements=tiny_displacements())
        g = solve_grasp(P, rngs(trial, P.n_agents), samples=2000, iterations=20)
        assert g.objective == solve_exact(P).objective


def test_threads_do_not_change_the_result(antenna):
    P = random_problem(np.random.default_rng(3), antenna)
    a = solve_grasp(P, rngs(1, 3), samples=300, iterations=5, threads=1)
    b = solve_grasp(P, rngs(1, 3), samples=300, iterations=5, threads=3)
    assert np.array_equal(a.move, b.move) and np.array_equal(a.level, b.level)


def test_same_seed_same_solution(antenna):
    P = random_problem(np.random.default_rng(4), antenna)
    a = solve_grasp(P, rngs(9, 3), samples=300, iterations=5)
    b = solve_grasp(P, rngs(9, 3), samples=300, iterations=5)
    assert np.array_equal(a.move, b.move) and np.array_equal(a.level, b.level)


def test_the_hot_sampling_loop_and_the_general_one_agree(antenna):
    """_sample_block's loop of its own for one objective sample and n <= 3 finds what its general
    loop finds on the same problem given as two samples weighted 1 and 0 (the same values, since
    0 + 1 v + 0 v = v): the same best value and control, and the same random stream consumed."""
    rng = np.random.default_rng(8)
    for trial in range(6):
        P = random_problem(rng, antenna, 3, 1 + trial % 3, constraints=trial % 2 == 0)
        p_s, w = P.objective_tables()
        N, L = P.n_agents, len(P.levels_w)
        p_flat = p_s.reshape(1, N, -1)
        pair_c = np.arange(p_flat.shape[2]) // L
        pair_l = np.arange(p_flat.shape[2]) % L
        M = P.n_cand * L
        results = []
        for tables, weights in ((p_flat, w), (np.concatenate([p_flat, p_flat]), np.array([1.0, 0.0]))):
            r = np.random.default_rng(trial)
            it_c, it_l = np.zeros(N, dtype=np.int64), np.zeros(N, dtype=np.int64)
            best = _sample_block(r, tables, weights, M, P.at_least, 0, 3000, np.empty(N, dtype=np.int64),
                                 np.empty(N, dtype=np.int64), np.empty(N, dtype=np.int64), np.empty(N),
                                 np.empty(P.at_least + 1), P.gain, P.levels_w, P.delta_w, P.constraints,
                                 pair_c, pair_l, it_c, it_l, -np.inf)
            results.append((best, it_c, it_l, r.random()))
        (b1, c1, l1, r1), (b2, c2, l2, r2) = results
        assert b1 > -np.inf and b1 == b2 and r1 == r2
        assert np.array_equal(c1, c2) and np.array_equal(l1, l2)


def test_one_agent_follows_its_twin_and_reaches_the_enumerated_optimum(antenna):
    """N = 1 (the other tests take two agents or more): the compiled search equals its numpy
    twin draw for draw, and with every one of its 28 pairs likely drawn it finds the optimum of
    the enumeration, the first in its order among equal values."""
    from trackjam.control.exact import enumerate_optimum

    rng = np.random.default_rng(13)
    for trial in range(4):
        P = random_problem(rng, antenna, 1, 1, constraints=trial % 2 == 0, displacements=tiny_displacements(),
                           spread=4.0)
        assert_grasp_kernel_follows_its_twin(P, trial, 100, 4)
        value, cand, level = enumerate_optimum(P)
        assert value > 0.0  # the agent can see the aim: the optimum is not the silent start
        g = solve_grasp(P, rngs(trial, 1), samples=500, iterations=5)
        assert g.objective == value


def test_neighbour_ties_go_to_the_lower_displacement_index(antenna):
    """The displacement sets are symmetric, so many candidates are exactly as far from a given
    one (the same distance table as the code, so ties are the code's ties): each list is the
    ``neighbours`` other candidates first in (distance, index) order, as a plain sorted() of
    the pairs gives them. An unstable argsort keeps the nearest distances but not the order."""
    for D, k in ((small_displacements(), 6), (tiny_displacements(), 4), (small_displacements(), 20)):
        P = random_problem(np.random.default_rng(1), antenna, displacements=D)
        neigh, n_neigh = neighbour_lists(P, k)
        for i in range(P.n_agents):
            n = int(P.n_cand[i])
            d = P.displacements[P.move[i, :n]]
            dist = np.linalg.norm(d[:, None, :] - d[None, :, :], axis=-1)
            assert len(np.unique(dist.round(9))) < n * (n - 1) // 2  # there are ties to break
            for c in range(n):
                expected = sorted((j for j in range(n) if j != c), key=lambda j: (dist[c, j], j))[:k]
                assert n_neigh[i, c] == min(k, n - 1)
                assert neigh[i, c, : n_neigh[i, c]].tolist() == expected
