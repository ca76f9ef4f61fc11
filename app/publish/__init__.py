"""`tcpcal publish`: the outbox sent to the plant (MQTT; OPC UA plugs in as another sink).

- app.services.audit.outbox writes the rows (in the transaction of each change);
- sink.py: what a publisher target implements (`Sink`) and what it is given (`Batch`);
- source.py: the database side: undelivered rows, current tool states, marking, pruning;
- lock.py: one publisher per fleet (PostgreSQL advisory lock, or an flock beside SQLite);
- runner.py: the loop; mqtt.py: the MQTT sink (paho-mqtt).

app.api and app.services never import this package (tests/test_publish_imports.py and
import-linter): the API keeps serving whether a publisher runs or not.
"""
