"""Tests of app/storage/: SQLite writers, held reads, migrations, restore."""
