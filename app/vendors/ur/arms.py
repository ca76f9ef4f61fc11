"""Universal Robots arms: the nominal kinematics of the e-Series, by the preset names the API
accepts (`{"preset": "ur5e"}`).

Each table gives the controller's flange frame, the `tool0`/"Tool flange" frame with an
all-zero TCP, in the controller's base frame.
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

#: The arms, as MAKER declares them.
ARMS: tuple[Kinematics, ...] = (UR3E, UR5E, UR10E, UR16E)
