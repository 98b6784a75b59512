"""The service: the job life cycle on the jobs table (:mod:`.jobs`), trade studies, quotas and cost,
the broker side the API and the worker share (:mod:`.broker`), the recovery loop and key numbers.

Layer rule: the service may import the kinds, the results machinery and the runtime, never the API
or the CLI; HTTP concerns (status codes, request objects) stay in :mod:`app.api`.
"""
