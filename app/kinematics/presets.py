"""Nominal kinematics of common arms, by the preset names the API accepts (`{"preset": "ur5e"}`).

Nominal means as designed: a real arm's factory calibration differs by up to a few tenths of
a millimetre, which is why a robot may carry its own DH links instead of a preset.
Every table gives the flange frame of the controller (UR: the `tool0`/"Tool flange" frame with
an all-zero TCP; Techman: the flange with an all-zero tool; Yaskawa: the flange, `tool0`, with
tool 0 all zero), in the controller's base frame (Yaskawa: its robot coordinates).
"""

from __future__ import annotations

from app.kinematics.dh_table import DHLink, Kinematics


def _ur(name: str, d1: float, a2: float, a3: float, d4: float, d5: float, d6: float) -> Kinematics:
    """A UR e-Series arm from its six published DH numbers (mm)."""
    return Kinematics(
        convention="dh",
        links=(
            DHLink(a_mm=0.0, alpha_deg=90.0, d_mm=d1, theta_offset_deg=0.0),
            DHLink(a_mm=a2, alpha_deg=0.0, d_mm=0.0, theta_offset_deg=0.0),
            DHLink(a_mm=a3, alpha_deg=0.0, d_mm=0.0, theta_offset_deg=0.0),
            DHLink(a_mm=0.0, alpha_deg=90.0, d_mm=d4, theta_offset_deg=0.0),
            DHLink(a_mm=0.0, alpha_deg=-90.0, d_mm=d5, theta_offset_deg=0.0),
            DHLink(a_mm=0.0, alpha_deg=0.0, d_mm=d6, theta_offset_deg=0.0),
        ),
        name=name,
    )


# Universal Robots e-Series, classic DH, from UR's support article "DH parameters for
# calculations of kinematics and dynamics" (article 45257,
# https://www.universal-robots.com/articles/ur/application-installation/dh-parameters-for-calculations-of-kinematics-and-dynamics/),
# tables in metres converted to mm. The same numbers generate the ROS description
# (ros-industrial/universal_robot ur_description/config/<model>/default_kinematics.yaml and
# UniversalRobots/Universal_Robots_ROS2_Description), which tests/kinematics checks against
# (UR10e: the same fields from ur_e_description/config/ur10e_default.yaml, the stored copy
# having no ur_description/config/ur10e/default_kinematics.yaml).
UR3E = _ur("ur3e", d1=151.85, a2=-243.55, a3=-213.2, d4=131.05, d5=85.35, d6=92.1)
UR5E = _ur("ur5e", d1=162.5, a2=-425.0, a3=-392.2, d4=133.3, d5=99.7, d6=99.6)
UR10E = _ur("ur10e", d1=180.7, a2=-612.7, a3=-571.55, d4=174.15, d5=119.85, d6=116.55)
UR16E = _ur("ur16e", d1=180.7, a2=-478.4, a3=-360.0, d4=174.15, d5=119.85, d6=116.55)

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

# Yaskawa Motoman GP12, classic DH, derived from ROS-Industrial's URDF (ros-industrial/motoman
# motoman_gp12_support/urdf/gp12_macro.xacro, BSD-3: joint_1_s at z 0.450 about +z,
# joint_2_l x 0.155 about +y, joint_3_u z 0.614 about -y, joint_4_r xyz (0.640, 0, 0.200)
# about -x, joint_5_b about -y and joint_6_t about -x at the same point; tool0 x 0.100 with
# rpy (pi, -pi/2, 0)). From its `base` link, Yaskawa's robot coordinates (450 mm above
# `base_link`, at the height of the L axis), to `tool0`, the flange: all-zero joints put
# the flange at (895, 0, 814) mm, its Z axis along the robot's X. Joint angles are the
# URDF's joint_1_s .. joint_6_t (what ROS-Industrial's driver publishes), in degrees. The
# negative d and the 180 deg twists follow the URDF's joint axes (-y, -x) and flange turn.
# tests/kinematics/test_presets_urdf.py checks it against the expanded URDF, kept in
# tests/data/urdf/ (tests/data/README.md: source, commit and licence).
YASKAWA_GP12 = Kinematics(
    convention="dh",
    links=(
        DHLink(a_mm=155.0, alpha_deg=-90.0, d_mm=0.0, theta_offset_deg=0.0),
        DHLink(a_mm=614.0, alpha_deg=180.0, d_mm=0.0, theta_offset_deg=-90.0),
        DHLink(a_mm=200.0, alpha_deg=-90.0, d_mm=0.0, theta_offset_deg=0.0),
        DHLink(a_mm=0.0, alpha_deg=90.0, d_mm=-640.0, theta_offset_deg=0.0),
        DHLink(a_mm=0.0, alpha_deg=-90.0, d_mm=0.0, theta_offset_deg=0.0),
        DHLink(a_mm=0.0, alpha_deg=180.0, d_mm=-100.0, theta_offset_deg=0.0),
    ),
    name="yaskawa_gp12",
)

#: Preset name (as in the API) -> nominal kinematics.
PRESETS: dict[str, Kinematics] = {
    k.name: k for k in (UR3E, UR5E, UR10E, UR16E, TM5_900, YASKAWA_GP12) if k.name is not None
}
