"""The simulators' fixtures for the connector tests (defined in tests.controllers.fixtures)."""

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
