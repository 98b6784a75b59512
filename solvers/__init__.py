"""trajlab numerics: pure functions and dataclasses, SI units, no web/queue/DB imports."""
