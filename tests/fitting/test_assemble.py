"""fitting.assemble: the rounding of the reported values."""

import numpy as np

from fitting import problem as P
from fitting.assemble import rounded_output


def test_rounded_output_is_np_round_to_the_last_bit():
    rng = np.random.default_rng(2)
    for i in range(2000):
        scale = 10.0 ** rng.integers(-6, 4)
        x, fixed, joints = rng.normal(size=19) * scale, rng.normal(size=8) * 50 * scale, rng.normal(size=(12, 3)) * scale
        if i % 3 == 0:   # halfway cases
            fixed = (np.round(fixed * 2e4) + 0.5) / 1e4
            joints = (np.floor(joints * 1e5) + 0.5) / 1e5
        want = np.concatenate((np.round(P.to_degrees(x), 4), np.round(fixed, 4), np.round(joints, 5).ravel()))
        assert np.array(rounded_output(x, fixed, joints)).tobytes() == want.tobytes()
