"""What an engineer takes away from a finished job: plots (matplotlib, rendered on the server),
CSV tables with unit-bearing headers, and a self-contained HTML report.  Everything here reads the
stored result JSON only; nothing calls a solver."""
