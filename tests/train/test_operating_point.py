"""The operating point of an adapted model (:mod:`fastdet.train.operating_point`): every lane run
once, the formation of best F1, the strictest offset within one standard error of the best (its
error checked against a plain bootstrap loop), the agreement's figures."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastdet.config.adapt import AdaptConfig
from fastdet.model import load_model
from fastdet.train import adapt, operating_point
from fastdet.train.operating_point import Agreement, FormationChoice, use_side
from tests.media import write_video


def test_the_formation_and_offset_are_chosen_in_one_run(tmp_path):
    a = write_video(tmp_path / "a.mp4", 20)
    fp = adapt.plan_footage([str(a)], AdaptConfig(every=5))
    calls: list[tuple[tuple[str, float], ...]] = []
    # every frame alike (no spread between frames: the standard error is 0, the best F1 wins; of
    # offsets with the very same counts, the one nearest 0): heat peaks at offsets 1 and 2 alike
    # (chosen: 1); nms at 2, and higher than heat's
    tp = {("heat", -1.0): 2, ("heat", 0.0): 3, ("heat", 1.0): 4, ("heat", 2.0): 4,
          ("nms", -1.0): 1, ("nms", 0.0): 2, ("nms", 1.0): 3, ("nms", 2.0): 5}

    def run(clip, model_path, lanes):
        assert load_model(model_path).intercept == load_model().intercept  # the model itself, not moved
        calls.append(tuple(lanes))
        return {k: np.array([(tp[k], 5 - tp[k], 5 - tp[k])] * 2) for k in lanes}, 0.5, 10

    offsets = (2.0, 1.0, 0.0, -1.0)
    boxes, chosen, by_boxes = operating_point.choose_operating_point(load_model(), fp, run, tmp_path / "op", offsets,
                                                           progress=False)
    assert (boxes, chosen) == ("nms", 2.0)
    assert calls == [tuple((b, o) for b in ("heat", "nms") for o in offsets)]  # one run for every lane
    heat = by_boxes["heat"]
    assert (heat.offset, heat.best, heat.se) == (1.0, 1.0, 0.0)
    assert heat.results[1.0].f1 == 0.8 and heat.results[0.0].to_dict()["f1"] == 0.6
    assert (heat.results[1.0].tp, heat.results[1.0].fp) == (8, 2)  # both frames summed
    assert heat.results[1.0].ms_per_frame == 50
    assert not list((tmp_path / "op").iterdir())  # the model file is removed
    # the heat map alone: its own best offset
    calls.clear()
    boxes, chosen, by_boxes = operating_point.choose_operating_point(load_model(), fp, run, tmp_path / "op", offsets,
                                                           formations=("heat",), progress=False)
    assert (boxes, chosen) == ("heat", 1.0) and set(by_boxes) == {"heat"} and len(calls[0]) == 4


def _bootstrap_se_loop(counts: np.ndarray, seed: int, draws: int) -> float:
    """The slow twin of the standard error: resample the frames one draw at a time."""
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(counts), (draws, len(counts)))
    f1s = []
    for row in idx:
        tp = fp = fn = 0
        for i in row:
            tp, fp, fn = tp + counts[i][0], fp + counts[i][1], fn + counts[i][2]
        f1s.append(2 * tp / (2 * tp + fp + fn) if 2 * tp + fp + fn else 0.0)
    return float(np.std(f1s))


def adapt_choice(per):
    return operating_point.strictest_within_one_se(per)


def test_the_strictest_offset_within_one_standard_error_is_chosen():
    """The best F1's offset, its bootstrap standard error over the frames (as a plain loop draws
    it), and the largest offset whose F1 is within it; one beyond it, or with no boxes and no
    targets at all, is never chosen."""
    frames = {  # four frames each: (tp, fp, fn)
        -1.0: [(4, 3, 0), (2, 2, 1), (3, 1, 0), (1, 2, 2)],  # best F1
        0.0: [(4, 2, 0), (2, 2, 1), (2, 1, 1), (1, 1, 2)],
        2.0: [(3, 1, 1), (2, 1, 1), (2, 1, 1), (1, 1, 2)],  # within one SE of the best
        4.0: [(1, 0, 3), (0, 0, 3), (1, 0, 2), (0, 0, 3)],  # far below
    }
    per = {o: np.array(v) for o, v in frames.items()}
    chosen, best, se = operating_point.strictest_within_one_se(per, seed=3, draws=150)
    f1 = {o: 2 * c[:, 0].sum() / (2 * c[:, 0].sum() + c[:, 1].sum() + c[:, 2].sum()) for o, c in per.items()}
    assert best == max(f1, key=f1.get) == -1.0
    assert se == pytest.approx(_bootstrap_se_loop(per[-1.0], 3, 150), abs=1e-12) and se > 0
    assert f1[2.0] >= f1[-1.0] - se > f1[4.0]
    assert chosen == 2.0
    # the same counts on every frame: no spread, the best wins
    same = {o: np.array([v[0]] * 4) for o, v in frames.items()}
    # F1 0.73 / 0.80 / 0.75 / 0.40
    assert operating_point.strictest_within_one_se(same) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    tied = {-1.0: np.array([(2, 1, 1)] * 3), 1.0: np.array([(2, 1, 1)] * 3), 3.0: np.array([(0, 0, 4)] * 3)}
    assert operating_point.strictest_within_one_se(tied) == pytest.approx((1.0, -1.0, 0.0), abs=1e-12)
    # a flat run (the same counts on every frame from -1 to 4, as on 3 frames of a short clip):
    # the frames tell those offsets nothing apart, so the one nearest 0 stands, not the strict end;
    # a stricter offset with other counts within the error is still preferred
    flat = {o: np.array([(1, 1, 3), (0, 0, 2), (1, 2, 1)]) for o in (-1.0, 0.0, 1.0, 2.0, 4.0)}
    flat[6.0] = np.array([(0, 0, 4), (0, 0, 2), (0, 1, 2)])
    assert adapt_choice(flat)[0] == 0.0
    flat[6.0] = np.array([(1, 0, 3), (0, 0, 2), (1, 1, 1)])  # fewer false alarms, the same hits
    assert adapt_choice(flat)[0] == 6.0
    # an offset with nothing at all (no boxes, no targets) is never the choice
    empty = {0.0: np.array([(1, 1, 1), (2, 0, 1)]), 8.0: np.zeros((2, 3), np.int64)}
    assert operating_point.strictest_within_one_se(empty)[0] == 0.0
    with pytest.raises(ValueError):
        operating_point.strictest_within_one_se({})


def test_the_box_formation_of_best_f1_at_its_best_offset_is_chosen_ties_keep_the_heat_map():
    def result(tp: int, fp: int) -> operating_point.FormationChoice:
        return operating_point.FormationChoice(0.0, {0.0: operating_point.Agreement(2, 8, 8, 0.0, 0),
                                           1.0: operating_point.Agreement(tp, fp, 10 - tp, 0.0, 0)}, 1.0, 0.0)

    assert operating_point.choose_boxes({"heat": result(5, 5), "nms": result(7, 3)}) == "nms"
    assert operating_point.choose_boxes({"heat": result(7, 3), "nms": result(5, 5)}) == "heat"
    assert operating_point.choose_boxes({"heat": result(6, 4), "nms": result(6, 4)}) == "heat"  # a tie
    assert operating_point.choose_boxes({"heat": result(0, 0), "nms": result(0, 0)}) == "heat"  # no F1 at all
    assert operating_point.choose_boxes({"nms": result(0, 0), "heat": result(0, 0)}) == "heat"  # whatever the order
    assert operating_point.choose_boxes({"heat": result(0, 0), "nms": result(1, 0)}) == "nms"


def test_agreement_without_boxes_is_not_a_number():
    a = operating_point.Agreement(0, 0, 0, 0.0, 0)
    assert math.isnan(a.f1) and a.to_dict()["f1"] is None and a.to_dict()["ms_per_frame"] is None


# ---- the side-view component's offset (choose_side_offset) --------------------------------


def _carrying_side():
    """The bundled model carrying a (random) side-view component."""
    from dataclasses import replace

    from fastdet.model import Model
    from fastdet.train.side import side_config

    main = load_model()
    cfg = side_config(main.config)
    rng = np.random.default_rng(0)
    n = cfg.n_features
    side = Model(cfg, rng.normal(size=n) * 0.01, -1.0, np.zeros(n), np.ones(n), classifier="logreg")
    return replace(main, side=side)


def _side_choice(tmp_path, per_frame, side_offsets=(2.0, 0.0)):
    """choose_side_offset over a fake run that gives each side offset ``per_frame[offset]``
    (``(K, 3)``, the same for every lane's formation and main offset); also the lanes it got."""
    a = write_video(tmp_path / "a.mp4", 20)
    fp = adapt.plan_footage([str(a)], AdaptConfig(every=5))
    model = _carrying_side()
    calls = []

    def run(clip, model_path, lanes):
        back = load_model(model_path)
        assert back.side is not None and back.side.intercept == model.side.intercept  # the component, unmoved
        calls.append(tuple(lanes))
        return {lane: np.asarray(per_frame[lane[2]]) for lane in lanes}, 0.5, 10

    choice = operating_point.choose_side_offset(model, fp, run, tmp_path / "op", "nms", 1.5, side_offsets,
                                                progress=False, seed=0)
    assert calls == [tuple(("nms", 1.5, k) for k in (*sorted(side_offsets), math.inf))]  # one run, every lane
    assert set(choice.results) == {*side_offsets, math.inf}
    assert not list((tmp_path / "op").iterdir())
    return choice


def test_the_side_component_is_left_out_when_it_is_not_clearly_better(tmp_path):
    """Left out (inf, the strictest) when its F1 is within one standard error of the best."""
    per = {0.0: [(4, 2, 0), (1, 2, 2), (3, 0, 1), (0, 1, 3)],  # the best F1, spread over the frames
           2.0: [(3, 2, 1), (1, 1, 2), (3, 0, 1), (0, 1, 3)],
           math.inf: [(3, 1, 1), (1, 1, 2), (2, 0, 2), (0, 1, 3)]}
    f1 = {k: operating_point._f1(np.array(v)[None])[0] for k, v in per.items()}
    choice = _side_choice(tmp_path, per)
    assert choice.best == 0.0 and choice.se > 0
    assert f1[0.0] > f1[math.inf] >= f1[0.0] - choice.se  # a worse F1, but within the error
    assert choice.offset == math.inf
    assert choice.results[math.inf].tp == 6 and choice.results[0.0].f1 == pytest.approx(f1[0.0])


def test_the_side_components_offset_is_chosen_when_it_is_clearly_better(tmp_path):
    per = {0.0: [(4, 3, 1)] * 3, 2.0: [(4, 1, 1)] * 3, 4.0: [(3, 1, 2)] * 3, math.inf: [(1, 0, 4)] * 3}
    choice = _side_choice(tmp_path, per, side_offsets=(0.0, 2.0, 4.0))
    assert (choice.offset, choice.best, choice.se) == (2.0, 2.0, 0.0)
    # the strictest offset within the error of the best: 4 when it is as good as 2 (other frames)
    per[4.0] = [(5, 1, 0), (4, 1, 1), (3, 1, 2)]
    assert _side_choice(tmp_path, per, side_offsets=(0.0, 2.0, 4.0)).offset == 4.0


def test_the_side_component_is_left_out_when_its_boxes_agree_as_those_without_it(tmp_path):
    """The rule alone would pick the offset nearest 0 of a run of offsets with the very same
    counts on every frame (the strict end included); where that run reaches 'left out', the
    component costs time for nothing and is left out."""
    same = [(3, 1, 1), (2, 0, 1), (1, 1, 0)]
    per = {0.0: [(3, 4, 1), (2, 3, 1), (1, 2, 0)], 2.0: same, 4.0: same, math.inf: same}
    assert operating_point.strictest_within_one_se({k: np.array(v) for k, v in per.items()})[0] == 2.0
    choice = _side_choice(tmp_path, per, side_offsets=(0.0, 2.0, 4.0))
    assert choice.offset == math.inf and choice.best == 2.0


def test_a_model_without_a_side_component_has_no_side_offset(tmp_path):
    a = write_video(tmp_path / "a.mp4", 20)
    fp = adapt.plan_footage([str(a)], AdaptConfig(every=5))

    def run(clip, model_path, lanes):
        raise AssertionError("not run")

    with pytest.raises(ValueError, match="no side-view component"):
        operating_point.choose_side_offset(load_model(), fp, run, tmp_path / "op", "nms", 0.0, (0.0,),
                                           progress=False)


def _choice(results: dict[float, tuple[int, int, int]], chosen: float):
    res = {o: Agreement(*c, seconds=1.0, frames=10) for o, c in results.items()}
    best = max(res, key=lambda o: res[o].f1)
    return FormationChoice(chosen, res, best, 0.01)


def test_the_side_component_is_kept_only_where_the_window_boxes_with_it_agree_best():
    heat = _choice({0.0: (8, 2, 2)}, 0.0)  # F1 0.80
    nms = _choice({0.0: (6, 4, 4)}, 0.0)  # F1 0.60
    left_out = _choice({0.0: (9, 1, 1), math.inf: (6, 4, 4)}, math.inf)
    assert not use_side("nms", {"heat": heat, "nms": nms}, left_out)
    better = _choice({2.0: (9, 1, 1), math.inf: (6, 4, 4)}, 2.0)  # F1 0.90 with it
    assert use_side("nms", {"heat": heat, "nms": nms}, better)
    assert use_side("heat", {"heat": heat, "nms": nms}, better)  # beats the heat map's 0.80
    worse = _choice({2.0: (7, 3, 3), math.inf: (6, 4, 4)}, 2.0)  # F1 0.70: below the heat map
    assert use_side("nms", {"heat": heat, "nms": nms}, worse)
    assert not use_side("heat", {"heat": heat, "nms": nms}, worse)
