"""The HTTP API: ``create_app()`` (:mod:`.main`), the routes (:mod:`.routes`), request and response
schemas, dependencies, error bodies, body limits, API keys and who may see a job (:mod:`.access`),
submission parameters (:mod:`.params`) and the typed result body (:mod:`.result_body`).

Layer rule: the API may import the service, the kinds, the results machinery and the runtime,
never the CLI or the worker (``pyproject.toml``, import-linter).
"""
