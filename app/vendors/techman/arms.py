"""Techman arms: the nominal kinematics of the TM5-900, by the preset name the API accepts
(`{"preset": "tm5_900"}`).

The table gives the controller's flange frame, the flange with an all-zero tool, in the
controller's base frame.
"""

from __future__ import annotations

from app.kinematics.dh_table import DHLink, Kinematics

# Techman TM5-900, classic DH, derived from Techman's nominal URDF
# (TechmanRobotInc/tmr_ros1 tm_description/xacro/macro.tm5-900-nominal.urdf.xacro, BSD-3,
# expanded by Techman as tm_description/urdf/tm5-900-nominal.urdf: joint origins z 0.1452;
# rpy (-pi/2, -pi/2, 0); x 0.429; xyz (0.4115, 0, -0.1223) yaw pi/2; y -0.106 roll pi/2;
# y -0.11315 roll pi/2; flange = link_6 = tool0, from `base` = link_0). The theta offsets
# -90/+90 on joints 2 and 4 make all-zero joints the upright "candle" pose, as on the TM
# pendant. tests/kinematics/test_presets_urdf.py checks it against that URDF, kept in
# tests/data/urdf/ (tests/data/README.md: source, commit and licence).
TM5_900 = Kinematics(
    convention="dh",
    links=(
        DHLink(a_mm=0.0, alpha_deg=-90.0, d_mm=145.2, theta_offset_deg=0.0),
        DHLink(a_mm=429.0, alpha_deg=0.0, d_mm=0.0, theta_offset_deg=-90.0),
        DHLink(a_mm=411.5, alpha_deg=0.0, d_mm=0.0, theta_offset_deg=0.0),
        DHLink(a_mm=0.0, alpha_deg=90.0, d_mm=-122.3, theta_offset_deg=90.0),
        DHLink(a_mm=0.0, alpha_deg=90.0, d_mm=106.0, theta_offset_deg=0.0),
        DHLink(a_mm=0.0, alpha_deg=0.0, d_mm=113.15, theta_offset_deg=0.0),
    ),
    name="tm5_900",
)

#: The arms, as MAKER declares them.
ARMS: tuple[Kinematics, ...] = (TM5_900,)
