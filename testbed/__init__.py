"""What the tests and the benchmarks share, outside both: the simulated ground truth
(`testbed.sim`: touches, planes, frames and laser sweeps of a known TCP, made with seeded
noise), a fresh database per backend (`testbed.databases`) and a real server on a loopback
port (`testbed.live_server`). bench/ imports nothing of tests/ (tests/test_house_rules.py
holds it): a benchmark's harness is not a test's to change.

Not in the wheel (pyproject.toml's packages are app*): like tests/ and bench/ it is used from
a checkout, whose root pytest and `python -m bench.x` put on sys.path, and it imports app
besides numpy, scipy, sqlalchemy and httpx, which the service's image needs none of here.
"""
