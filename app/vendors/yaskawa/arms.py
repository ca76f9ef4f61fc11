"""Yaskawa arms: the nominal kinematics of the Motoman GP12, by the preset name the API
accepts (`{"preset": "yaskawa_gp12"}`).

The table gives the controller's flange frame, the flange, `tool0`, with tool 0 all zero,
in the controller's robot coordinates.
"""

from __future__ import annotations

from app.kinematics.dh_table import DHLink, Kinematics

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

#: The arms, as MAKER declares them.
ARMS: tuple[Kinematics, ...] = (YASKAWA_GP12,)
