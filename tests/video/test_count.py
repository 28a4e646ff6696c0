"""Counting vehicles (fastdet.video.count): ids seen often enough, and crossings of a line
per direction."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.detections import Detections
from fastdet.video.count import CountLine, VehicleCounter
from tests.video.test_track import car


def test_count_line_sides_and_crossings():
    ln = CountLine(0, 100, 200, 100)  # drawn left to right: its right side is below it
    assert ln.side(np.array([[50, 150], [50, 50]])).tolist() == [10000.0, -10000.0]
    assert ln.crossed(np.array([50, 90]), np.array([50, 110])) == 1  # downwards: left -> right
    assert ln.crossed(np.array([50, 110]), np.array([50, 90])) == -1
    assert ln.crossed(np.array([250, 90]), np.array([250, 110])) == 0  # past the segment's end
    assert ln.crossed(np.array([50, 90]), np.array([60, 95])) == 0
    assert ln.crossed(np.array([50, 90]), np.array([50, 100])) == 0  # touching is not crossing
    assert CountLine.parse(" 1, 2,3,4") == CountLine(1, 2, 3, 4)
    # issue 34 (17): 1e308 is finite but its cross products are not (NaN crossing tests)
    for bad in ("1,2,3", "a,b,c,d", "1,2,1,2", "1,2,3,inf", "0,0,1e308,1e308", "0,0,1e200,5"):
        with pytest.raises(ValueError):
            CountLine.parse(bad)


def test_vehicle_counter_counts_ids_and_crossings_once_per_direction():
    # car 1 moves right across a vertical line at x = 200 (bottom centre from x = 130);
    # car 2 waits left of it; car 3 goes right then comes back
    line = CountLine(200, 0, 200, 480)  # drawn downwards: its right side is the picture's left
    c = VehicleCounter(line)
    for f in range(20):
        b1 = car(100, f, 10)
        b2 = car(0, 0, 0)
        x3 = 150 + (10 * f if f < 10 else 10 * (20 - f))
        c.update(Detections(np.array([b1, b2, [x3, 300, x3 + 40, 330]], np.int32), np.ones(3, np.float32),
                            ids=np.array([1, 2, 3])))
    assert c.vehicles == 3
    s = c.summary()
    assert s["line"]["right_to_left"] == 2  # cars 1 and 3 went left -> right in the picture
    assert s["line"]["left_to_right"] == 1  # car 3 came back
    assert "3 vehicles" in c.text() and "2 right to left" in c.text()
    assert VehicleCounter().summary() == {"vehicles": 0}


def test_vehicle_counter_leaves_out_glimpses():
    # id 1 seen in 5 frames, id 2 in 2 (crossing the line meanwhile): only id 1 counts
    c = VehicleCounter(CountLine(0, 100, 200, 100), min_frames=3)
    for f in range(5):
        boxes = [[10, 50, 50, 80]] + ([[100, 60 + 40 * f, 140, 90 + 40 * f]] if f < 2 else [])
        c.update(Detections(np.array(boxes, np.int32), np.ones(len(boxes), np.float32),
                            ids=np.arange(1, len(boxes) + 1)))
    assert c.vehicles == 1 and c.ids == {1}
    assert c.crossed["left_to_right"] == {2} and c.crossings() == {"left_to_right": 0, "right_to_left": 0}
    assert VehicleCounter(min_frames=1).min_frames == 1
    with pytest.raises(ValueError):
        VehicleCounter(min_frames=0)
