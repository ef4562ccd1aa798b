"""A small rgb_array frame (``render_size``) on both environments: the returned shape, the
figure fitted inside it with its aspect kept, the whole figure without it, and one clear error
for every size that is not one (a huge one included)."""

import re

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.env import parallel_env
from trackjam.env.parallel import MAX_RENDER_SIDE

from swarm_scenarios import two_targets

ONE = ["steps=2", "filter.particles=200", "filter.birth_particles=50", "control.solver=greedy"]


def one_env(**kw):
    return parallel_env(load_scenario("paper-fig3", ONE), **kw)


def two_env(**kw):
    return parallel_env(two_targets("steps=2"), **kw)


MAKERS = pytest.mark.parametrize("make", [one_env, two_env], ids=["one-target", "two-targets"])


def stepped(env):
    env.reset(seed=1)
    n = len(env.action_space("agent_0").nvec)
    env.step({a: np.array([0, 2, 1][:n]) for a in env.agents})
    return env


def blank_rows_and_columns(img):
    """How many rows and columns are pure white (the margins a fitted frame adds)."""
    white = (img == 255).all(axis=2)
    return int(white.all(axis=1).sum()), int(white.all(axis=0).sum())


@MAKERS
def test_render_size_gives_a_frame_of_that_many_pixels_with_the_figure_fitted(make):
    full = stepped(make(render_mode="rgb_array")).render()
    h, w = full.shape[:2]
    assert h > 300 and w > 300  # without render_size, the whole figure as before
    for size in [(96, 64), (64, 200), (300, 40)]:
        env = stepped(make(render_mode="rgb_array", render_size=size))
        img = env.render()
        assert img.shape == (size[1], size[0], 3) and img.dtype == np.uint8
        assert img.min() < 128  # something is drawn
        rows, cols = blank_rows_and_columns(img)
        # the figure keeps its aspect: the side it is narrower on is padded, by about the lost share
        fit_w, fit_h = (size[0], h * size[0] / w) if size[0] / w < size[1] / h else (w * size[1] / h, size[1])
        assert rows >= round(size[1] - fit_h) - 2 and cols >= round(size[0] - fit_w) - 2
    env = stepped(make(render_mode="rgb_array", render_size=np.array([40, 30])))
    assert env.render().shape == (30, 40, 3)


@MAKERS
@pytest.mark.parametrize("bad", [(0, 64), (64, -1), (MAX_RENDER_SIDE + 1, 64), (10**6, 10**6), (2**63, 2),
                                 (64.0, 48), (True, 48), (64,), (64, 48, 3), "64x48", 64, {"w": 64, "h": 48}])
def test_a_render_size_that_is_not_one_is_named_at_construction(make, bad):
    with pytest.raises(ValueError, match=r"^render_size: expected \(width, height\), two whole numbers of pixels "
                                         rf"in \[1, 4096\], got {re.escape(repr(bad))}$"):
        make(render_mode="rgb_array", render_size=bad)


@pytest.mark.parametrize("make, mode", [(one_env, None), (one_env, "replay"), (two_env, None), (two_env, "replay")],
                         ids=["one-target-none", "one-target-replay", "two-targets-none", "two-targets-replay"])
def test_a_render_size_without_rgb_array_is_refused(make, mode, tmp_path):
    with pytest.raises(ValueError, match=rf"^render_size: \(64, 48\) given with render_mode={mode!r}"):
        make(render_mode=mode, render_size=(64, 48), replay_path=str(tmp_path / "r.html"))


@MAKERS
def test_render_replay_writes_the_page_and_returns_its_path(make, tmp_path):
    path = tmp_path / "replay.html"
    env = stepped(make(render_mode="replay", replay_path=str(path)))
    assert env.render() == path
    page = path.read_text()
    assert "<title>trackjam replay: " in page and page.count("Plotly.newPlot") == 1
