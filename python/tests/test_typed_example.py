# The typed example (checked by mypy --strict in scripts/python-test.sh) runs and answers as the
# plane it samples: heights row + col on a 1 m grid, a plane of slope atan(sqrt(2)).
import math

import numpy as np

from typed_example import run


def test_typed_example_runs():
    got = run()
    # The ramp's plane: the height at map (x, y) is (4 - y - 0.5) + (x - 0.5) (row + col at centres).
    assert got["floor"] == np.float64((4 - 2.5 - 0.5) + (1.5 - 0.5))
    assert math.isnan(got["ceiling"])
    assert got["polygon"] >= 0
    assert abs(got["slope"] - math.degrees(math.atan(math.sqrt(2)))) < 1e-9
