"""The controller simulators' fixtures for the connectors' tests of each maker
(defined in tests.controllers.fixtures, beside the simulators)."""

from tests.controllers.fixtures import (
    abb_rws1_sim,
    abb_rws2_sim,
    fanuc_sim,
    kuka_sim,
    techman_sim,
    ur_sim,
    yaskawa_sim,
)

__all__ = [
    "abb_rws1_sim",
    "abb_rws2_sim",
    "fanuc_sim",
    "kuka_sim",
    "techman_sim",
    "ur_sim",
    "yaskawa_sim",
]
