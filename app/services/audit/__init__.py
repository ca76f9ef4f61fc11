"""The audit trail: every write recorded in its own transaction (writes), read back by
GET /v1/audit (reads), and what the plant must hear of, written with it (outbox).
"""
