"""KRL and RAPID value texts: what the connectors write reads back (property tests)."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from app.vendors.abb.text import RapidTool, format_tooldata, parse_tooldata
from app.vendors.kuka.text import format_struct, parse_struct

FAST = settings(
    max_examples=200, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
reals = st.floats(-1e5, 1e5, allow_nan=False, allow_infinity=False)
unit = st.floats(-1, 1, allow_nan=False)


@FAST
@given(st.tuples(reals, reals, reals, reals, reals, reals))
def test_a_krl_frame_written_reads_back_to_its_six_decimals(values: tuple[float, ...]) -> None:
    names = ("X", "Y", "Z", "A", "B", "C")
    text = format_struct(dict(zip(names, values, strict=True)))
    assert "e" not in text.lower()
    parsed = parse_struct(text)
    for name, value in zip(names, values, strict=True):
        held = parsed[name]
        assert isinstance(held, float)
        assert abs(held - value) <= 5e-7 + 1e-12 * abs(value)


@FAST
@given(
    st.booleans(),
    st.tuples(reals, reals, reals),
    st.tuples(unit, unit, unit, unit),
    st.floats(0, 1000, allow_nan=False),
    st.tuples(reals, reals, reals),
)
def test_a_rapid_tooldata_written_reads_back(
    robhold: bool,
    position: tuple[float, float, float],
    quaternion: tuple[float, float, float, float],
    mass: float,
    cog: tuple[float, float, float],
) -> None:
    tool = RapidTool(
        robhold, position, quaternion, mass, cog, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    )
    back = parse_tooldata(format_tooldata(tool))
    assert back.robhold is robhold
    assert all(abs(a - b) <= 5e-7 for a, b in zip(back.position_mm, position, strict=True))
    assert all(abs(a - b) <= 5e-10 for a, b in zip(back.quaternion, quaternion, strict=True))
    assert abs(back.mass_kg - mass) <= 5e-7
    assert back.aom == (1.0, 0.0, 0.0, 0.0)
