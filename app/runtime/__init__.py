"""The runtime every layer stands on: settings (:mod:`.settings`), the database engine and tables
(:mod:`.db`, :mod:`.models`), migrations (:mod:`.migrate`), the supervisor of ``trajlab serve``'s
children (:mod:`.embedded`) and ``trajlab api``'s processes (:mod:`.serving`).

Layer rule: the runtime imports no other part of ``app`` (the bottom layer).
"""
