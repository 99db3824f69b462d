"""Fixtures of the daemon tests: the RealSense recording with depth that the hal tests make from the real
squat video (``squat_db3``), for the depth path through ``posed run``."""

from tests.hal.conftest import squat_db3, squat_frames, squat_imu_db3, squat_video  # noqa: F401
