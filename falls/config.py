"""Configuration of fall detection (section ``falls``).

Every detector threshold's reason is given in docs/falls.md. "rel" values are fractions of the person's
standing pelvis height (learned while they stand, otherwise the fitted leg length), so they hold for tall
and short people and need no metric calibration.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class HouseholdMember:
    """Someone who lives here (``falls.household``): recognised by their stature (docs/falls.md, "Who is who")."""

    name: str = field(metadata={"doc": "how status, history and events name them (required)",
                                "pattern": r"[^\x00-\x1f]{1,64}"})
    height_m: float = field(default=1.65, metadata={"doc": "their stature, standing, without shoes as far as "
                                                           "they go without at home", "unit": "m",
                                                    "range": (0.9, 2.3)})


@dataclass(frozen=True)
class FallsConfig:
    """Fall detector thresholds; each one's reason is in docs/falls.md."""

    enabled: bool = field(default=True, metadata={"doc": "run the fall detector"})
    alarm_after_s: float = field(
        default=10.0, metadata={"doc": "on the floor this long without recovering raises the alarm",
                                "unit": "s", "range": (0.0, 600.0)}
    )
    camera_tilt_deg: float = field(
        default=0.0, metadata={"doc": "camera pitch, down positive (for trunk inclination against gravity)",
                               "unit": "deg", "range": (-90.0, 90.0)}
    )
    camera_roll_deg: float = field(
        default=0.0, metadata={"doc": "camera roll about its optical axis, clockwise in the image positive",
                               "unit": "deg", "range": (-90.0, 90.0)}
    )
    camera_geometry: str = field(
        default="auto", metadata={"doc": "how far the configured camera_tilt_deg, camera_roll_deg and camera_height_m "
                                         "are trusted: measured (for this mount), guess (checked against the "
                                         "person's standing body: one that contradicts the tilt and roll by more "
                                         "than 20 deg replaces them and the height), auto (measured when any of the "
                                         "three differs from its default 0, 0, 1.0, otherwise guess; the tilt "
                                         "and roll, though, only when one of them was set: a height set with "
                                         "the tilt left at 0 is trusted while the tilt is checked against the "
                                         "body); see docs/falls.md",
                                  "choices": ("auto", "measured", "guess")}
    )
    camera_tilt_auto: bool = field(
        default=False, metadata={"doc": "learn the tilt from a person standing or walking at several places across "
                                        "the image (camera_tilt_deg is used until then, at least 5 s of standing); "
                                        "see docs/falls.md"}
    )
    camera_roll_auto: bool = field(
        default=False, metadata={"doc": "learn the roll from a person standing or walking (camera_roll_deg is used "
                                        "until 5 s of standing were seen)"}
    )
    imu_gravity: bool = field(
        default=True, metadata={"doc": "use the camera's IMU gravity when a frame carries it (a RealSense with an "
                                       "accelerometer and source.imu, or a recording's \"gravity\"); it "
                                       "replaces the tilt and roll, set or learned"}
    )
    floor_from_depth: bool = field(
        default=True, metadata={"doc": "with a depth camera (a RealSense, live or recorded), measure the floor plane "
                                       "in the depth image about once a second: it gives the camera height, and the "
                                       "tilt and roll unless an IMU does, ahead of anything configured or learned; "
                                       "see docs/falls.md"}
    )
    camera_mount_from_bus: bool = field(
        default=False, metadata={"doc": "take the camera's pose from the robot: its software puts gravity in the "
                                        "camera's axes (or tilt and roll) and the camera's height on Zenoh key "
                                        "posed/ROBOT/camera/mount; while a pose holds it comes first, ahead of the "
                                        "IMU, the depth floor, learned and configured values; off: no subscriber; "
                                        "see docs/falls.md"}
    )
    camera_height_m: float = field(
        default=1.0, metadata={"doc": "camera height above the floor (set it for your robot); 0 = unknown: "
                                      "the floor is then learned from a standing person only",
                               "unit": "m", "range": (0.0, 5.0)}
    )
    camera_hfov_deg: float = field(
        default=69.0, metadata={"doc": "field of view of the lens assumed when the frame has no intrinsics, by "
                                       "the fall detector and the fit, across the image's longer side "
                                       "(horizontal unless the camera is turned to portrait; 69 = RealSense "
                                       "D4xx colour)", "unit": "deg", "range": (10.0, 170.0)}
    )
    learn_floor: bool = field(
        default=True, metadata={"doc": "refine the floor height from the feet of a person standing upright"}
    )
    fall_velocity_rel: float = field(
        default=1.2, metadata={"doc": "pelvis descent speed that marks a fall, standing pelvis heights per "
                                      "second (1.2 = about 1 m/s)", "unit": "1/s", "range": (0.2, 10.0)}
    )
    floor_pelvis_rel: float = field(
        default=0.22, metadata={"doc": "pelvis below this height (rel) is at floor level (sitting on the floor)",
                                "range": (0.05, 0.9)}
    )
    lying_pelvis_rel: float = field(
        default=0.35, metadata={"doc": "lying counts as on the floor with the pelvis below this height (rel); "
                                       "a bed or sofa is higher", "range": (0.05, 1.0)}
    )
    lying_trunk_deg: float = field(
        default=60.0, metadata={"doc": "trunk inclined more than this from vertical counts as lying",
                                "unit": "deg", "range": (20.0, 90.0)}
    )
    lying_shoulder_rel: float = field(
        default=0.60, metadata={"doc": "the mid-shoulder below this height (rel) counts as lying",
                                "range": (0.1, 2.0)}
    )
    impact_window_s: float = field(
        default=1.5, metadata={"doc": "a fast descent counts as a fall when floor level is reached within this",
                               "unit": "s", "range": (0.2, 10.0)}
    )
    confirm_s: float = field(
        default=0.3, metadata={"doc": "after a fast descent, the body stays at floor level this long before "
                                      "the fall is reported", "unit": "s", "range": (0.0, 5.0)}
    )
    lost_confirm_s: float = field(
        default=0.5, metadata={"doc": "a fast descent that reached floor level (or low with the trunk tipping "
                                      "over), then the person not seen for this long, is reported as a fall "
                                      "(falling, feature lost_after_descent)", "unit": "s", "range": (0.1, 5.0)}
    )
    lost_descent_confirm_s: float = field(
        default=0.2, metadata={"doc": "the same, sooner, judged on the descent itself: when the last frames seen "
                                      "were already lying-like (trunk past lying_trunk_deg, pelvis below "
                                      "lying_pelvis_rel) or the descent was twice fall_velocity_rel with the trunk "
                                      "tipping over and heading for floor level (feature judged_on_descent, lower "
                                      "confidence); more than one frame period, so one dropped frame never "
                                      "raises it", "unit": "s", "range": (0.05, 5.0)}
    )
    on_floor_confirm_s: float = field(
        default=1.0, metadata={"doc": "lying at floor level without a fast descent (slow fall, found lying) "
                                      "this long is reported", "unit": "s", "range": (0.1, 60.0)}
    )
    recover_s: float = field(
        default=2.0, metadata={"doc": "up (pelvis high, trunk upright) this long after a fall counts as "
                                      "recovered", "unit": "s", "range": (0.1, 600.0)}
    )
    recover_pelvis_rel: float = field(
        default=0.45, metadata={"doc": "pelvis above this height (rel) is up", "range": (0.1, 1.5)}
    )
    recover_trunk_deg: float = field(
        default=45.0, metadata={"doc": "trunk within this of vertical is up", "unit": "deg",
                                "range": (5.0, 90.0)}
    )
    upright_trunk_deg: float = field(
        default=20.0, metadata={"doc": "standing reference: trunk within this of vertical", "unit": "deg",
                                "range": (1.0, 60.0)}
    )
    upright_knee_deg: float = field(
        default=25.0, metadata={"doc": "standing reference: hips and knees flexed less than this",
                                "unit": "deg", "range": (1.0, 90.0)}
    )
    velocity_window_s: float = field(
        default=0.3, metadata={"doc": "pelvis velocity is the slope over this much capture time",
                               "unit": "s", "range": (0.05, 2.0)}
    )
    max_gap_s: float = field(
        default=1.0, metadata={"doc": "frames lost (no person, failed fit) up to this long are bridged",
                               "unit": "s", "range": (0.0, 10.0)}
    )
    min_visibility: float = field(
        default=0.5, metadata={"doc": "a landmark counts when its visibility and presence reach this; "
                                      "shoulders and hips must count for a frame to be judged",
                               "range": (0.0, 1.0)}
    )
    bbox_wide_ratio: float = field(
        default=1.2, metadata={"doc": "supporting feature: landmark box wider than tall by this ratio",
                               "range": (0.2, 10.0)}
    )
    flexion_rate_deg_s: float = field(
        default=200.0, metadata={"doc": "supporting feature: hip or knee flexing faster than this (paper "
                                        "Figure 16)", "unit": "deg/s", "range": (10.0, 5000.0)}
    )
    household: tuple[HouseholdMember, ...] = field(
        default=(), metadata={"doc": "who lives here, each {name, height_m}; with several people in view, the "
                                     "person whose measured stature matches one of them is theirs, and status and "
                                     "history follow the household (the first listed first), not a visitor; needs "
                                     "a measured camera height and tilt or a depth camera; empty: every person is "
                                     "watched alike; see docs/falls.md"}
    )
    history_enabled: bool = field(default=True, metadata={"doc": "store per-frame joint angles in history.sqlite3 in the state dir"})
    history_rate_hz: float = field(
        default=5.0, metadata={"doc": "joint-angle history: frames kept per second (capture time)", "unit": "Hz", "range": (0.1, 60.0)}
    )
    history_commit_every_s: float = field(
        default=5.0, metadata={"doc": "joint-angle history: rows are written in batches this far apart", "unit": "s",
                               "range": (0.1, 600.0)}
    )
    history_downsample_after_h: float = field(
        default=24.0, metadata={"doc": "joint-angle history: rows older than this are averaged into buckets", "unit": "h",
                                "range": (0.0, 87600.0)}
    )
    history_downsample_period_s: float = field(
        default=10.0, metadata={"doc": "joint-angle history: bucket length for old rows", "unit": "s", "range": (0.1, 86400.0)}
    )
    history_retention_days: float = field(
        default=90.0, metadata={"doc": "joint-angle history: rows older than this are deleted", "unit": "d", "range": (0.01, 36500.0)}
    )

    absence_enabled: bool = field(
        default=True, metadata={"doc": "say when the person has not been seen for longer than on any of the last "
                                       "absence_days days at this time of day (hooks.on_absent, the status's "
                                       "presence); learned from the history, so nothing without history_enabled; "
                                       "see docs/daemon.md"}
    )
    absence_margin_h: float = field(
        default=1.0, metadata={"doc": "the notice comes this long after the latest the person was back on any of "
                                      "those days (1 h: a long lie on the floor, of an hour or more, is what "
                                      "studies of older people's falls tie to serious harm)", "unit": "h",
                               "range": (0.1, 48.0)}
    )
    absence_learn_days: int = field(
        default=7, metadata={"doc": "past days (each watched at least half the day) needed before an absence is "
                                    "judged; until then the status says learning", "range": (1, 90)}
    )
    absence_days: int = field(
        default=14, metadata={"doc": "past days the usual time until the person is back is learned from (the "
                                     "history keeps history_retention_days)", "range": (1, 90)}
    )

    def __post_init__(self) -> None:
        problems = []
        names = [m.name for m in self.household]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            problems.append(f"household: each member needs a name of their own; named twice: {', '.join(twice)}")
        if self.absence_learn_days > self.absence_days:
            problems.append(f"absence_learn_days: {self.absence_learn_days} is more than falls.absence_days "
                            f"({self.absence_days}); the routine is learned from the last absence_days days, so "
                            "no more of them can count: lower absence_learn_days or raise absence_days")
        if problems:
            raise ValueError("; ".join(problems))
