"""What is kept: the engine, its sessions and the held reads and driver writes (db), the
tables (models), the schema's migrations (migrate; the Alembic scripts are in
migrations/) and backups (backup).
"""
