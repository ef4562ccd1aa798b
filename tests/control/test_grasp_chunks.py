"""GRASP in chunks (Ctrl-C and a stop flag are answered between compiled calls): any chunk size
gives the one-call search's draws and result, a set stop flag ends the search early, and the
searches of a team stop when one of them is interrupted."""

import threading
import time

import numpy as np
import pytest

from trackjam.control.grasp import (
    GRASP_CHUNK_SAMPLES,
    grasp_search_chunked,
    neighbour_lists,
    run_in_chunks,
    run_searches,
)
from trackjam.control.problem import build_problem

from control_instances import random_problem

ONE_CALL = 2**62  # a chunk no search reaches: the whole search in one compiled call


def _both(P, me, seed, samples, iterations, chunk, stop=None):
    neigh, n_neigh = neighbour_lists(P, 4)
    args = (P.gain, P.levels_w, P.delta_w, P.at_least, P.constraints, P.n_cand, neigh, n_neigh, samples, iterations)
    c1, l1 = np.zeros(P.n_agents, dtype=np.int64), np.zeros(P.n_agents, dtype=np.int64)
    c2, l2 = c1.copy(), l1.copy()
    r1, r2 = np.random.default_rng(seed), np.random.default_rng(seed)
    v1 = grasp_search_chunked(r1, me, P.objective_tables(), *args, c1, l1, None, ONE_CALL)
    v2 = grasp_search_chunked(r2, me, P.objective_tables(), *args, c2, l2, stop, chunk)
    return (v1, c1, l1, r1), (v2, c2, l2, r2)


@pytest.mark.parametrize("chunk", [1, 7, 50, 10**9])
def test_any_chunk_size_gives_the_one_call_search(antenna, chunk):
    rng = np.random.default_rng(11)
    for trial in range(6):
        P = random_problem(rng, antenna, 3, 1 + trial % 3, constraints=trial % 2 == 0)
        for me in range(P.n_agents):
            (v1, c1, l1, r1), (v2, c2, l2, r2) = _both(P, me, 100 + trial, 40, 6, chunk)
            assert v1 == v2 and np.array_equal(c1, c2) and np.array_equal(l1, l2)
            assert r1.random() == r2.random()  # the same stream consumed


def test_chunks_give_the_one_call_search_over_a_belief_and_with_infeasible_iterations(antenna):
    rng = np.random.default_rng(5)
    x = np.array([50.0, 50.0, 50.0])
    u = x + np.array([[3.0, 0, 0], [-3.0, 0, 0], [0, 3.0, 0]])  # close together: most samples jam someone
    D = random_problem(rng, antenna).displacements
    samples = x + rng.normal(0, 3, (5, 3))
    P = build_problem(u, x, D, antenna, (0, 0, 0), (100, 100, 100), 2, True, samples=samples)
    for me in range(3):
        (v1, c1, l1, r1), (v2, c2, l2, r2) = _both(P, me, 7, 3, 20, 2)  # 3 samples an iteration: some all infeasible
        assert v1 == v2 and np.array_equal(c1, c2) and np.array_equal(l1, l2)
        assert r1.random() == r2.random()


def test_a_set_stop_flag_ends_the_search_after_one_chunk(antenna):
    P = random_problem(np.random.default_rng(3), antenna)
    stop = threading.Event()
    stop.set()
    (_, _, _, r_full), (v, c, l, r_cut) = _both(P, 0, 9, 100, 50, 100, stop)
    # one chunk of 100 samples is the first iteration's sampling; the full search drew 50 times that
    assert np.isfinite(v) and c.shape == (P.n_agents,)
    assert r_cut.random() != r_full.random()


def test_run_in_chunks_stops_between_calls():
    calls = []
    stop = threading.Event()

    def step(k):
        calls.append(k)
        if len(calls) == 3:
            stop.set()
        return len(calls) >= 10

    assert run_in_chunks(step, stop, 5) is False and calls == [5, 5, 5]
    calls.clear()
    assert run_in_chunks(step, None, 5) is True and len(calls) == 10
    assert GRASP_CHUNK_SAMPLES >= 10_000 * 100  # the default search is one call


@pytest.mark.parametrize("threads", [1, 3])
def test_an_interrupted_search_stops_the_others(threads):
    stopped = []

    def search(k, stop):
        if k == 0:
            raise KeyboardInterrupt
        t0 = time.monotonic()
        while not stop.is_set():  # a long search, checking its flag between chunks
            if time.monotonic() - t0 > 30:
                raise AssertionError("never told to stop")
            time.sleep(0.01)
        stopped.append(k)

    with pytest.raises(KeyboardInterrupt):
        run_searches(search, 3, threads)
    assert sorted(stopped) == ([] if threads == 1 else [1, 2])


@pytest.mark.parametrize("chunk", [1, 13, 10**9])
@pytest.mark.parametrize("objective", ["sum", "min"])
def test_the_assignment_search_in_chunks_is_the_one_call_search(antenna, chunk, objective):
    from trackjam.control.assignment_grasp import assignment_grasp_chunked
    from control_instances import small_displacements
    from test_assignment import random_assignment

    rng = np.random.default_rng(2)
    for n_targets in (1, 2, 3):
        P = random_assignment(rng, antenna, 3, n_targets, 2, True, objective, small_displacements(), spread=4.0)
        neigh, n_neigh = neighbour_lists(P.targets[0], 4)
        args = (P.pz, P.gain, P.levels_w, P.delta_w, P.at_least, P.kind, P.constraints, P.n_cand, neigh, n_neigh,
                9, 8)  # 9 samples an iteration: some iterations find nothing feasible
        for me in range(P.n_agents):
            p1, t1 = np.zeros(P.n_agents, dtype=np.int64), np.zeros(P.n_agents, dtype=np.int64)
            p2, t2 = p1.copy(), t1.copy()
            r1, r2 = np.random.default_rng(me), np.random.default_rng(me)
            v1 = assignment_grasp_chunked(r1, me, *args, p1, t1, None, ONE_CALL)
            v2 = assignment_grasp_chunked(r2, me, *args, p2, t2, None, chunk)
            assert v1 == v2 and np.array_equal(p1, p2) and np.array_equal(t1, t2)
            assert r1.random() == r2.random()
