"""One lifecycle for every calibrated subject (a tool's TCP today, a frame next): versions and
their numbering, activation with its rules, rollback by history, the drift trend and the audit
events, written once and taking the subject's declaration (app.services.lifecycle.subject).
A subject's package declares its `Subject` and adds its schemas, methods and routes."""
