"""Submitting a calibration: solve, grade, version, activate, store, all in one transaction
(POST .../calibrations, app/api/calibrations.py), and the same solve with nothing stored
(POST /v1/solve, app/api/solve.py).

The path is typed end to end: a request model (one per method, app.methods) -> the
method's run -> `Solved` -> one `CalibrationResult`, which is what is stored and served.
Nothing is written before the solver succeeds, so unsolvable input (a 422) leaves no row.
The tool row is locked first (SELECT ... FOR UPDATE; BEGIN IMMEDIATE on SQLite), which
serialises version numbering and makes idempotency-key replays see the first response.

One module per concern, each name imported from the module that defines it:
- submissions: the use case POST .../calibrations starts from (held reads, solver pool, write);
- stateless: the use case POST /v1/solve starts from;
- grading: a request solved by its method and its result graded (`solve`);
- presolve: the snapshot a calibration solves against before its transaction;
- writes: the transaction that stores it (`submit`; `solve_and_submit` for a solver process);
- stored: stored calibrations as served;
- detached: POST /v1/solve's solve, with nothing stored (run in a solver process);
- contexts: what a method reads (the robot, the active frame, reference points, lasers);
- verdict: the sentences and refusals a result is given.
"""
