"""Host-side tools for tempcomp (run with .venv/bin/python -m tools.<name>)."""
