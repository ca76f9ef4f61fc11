"""The use cases: one transaction each, called by the routers, the CLI and the publisher.

One package per feature:
- audit/: the trail written with every change, read back, and forwarded to the plant;
- robots/: a robot, its tool numbers, its controller connection, the TCP it moves by;
- tools/: a tool, its TCP versions and activation, its drift, the active TCP served;
- calibrations/: touches to a stored TCP (submissions, the solve with nothing stored);
- sessions/: guided calibration sessions;
- checks/: checks and the re-check after a collision;
- references/: reference points and laser devices;
- touches/: what the four above read touches with (the tool's frame, mix-ups refused);
- controllers/: deployments, captured touches, the reconcile and its watcher;
- fleet/: the fleet's rows and attention codes, gauges, what the plant is shown.
Beside them, what every feature uses: visible (rows not archived, within the caller's
cells), idempotency (replayed answers), solve_pool (the solver processes); and the API keys
(keys) and whether this server may take traffic (readiness).
"""
