"""Presenting a run: figures, report.html and its parts, the tables and the
one output writer. Reads the judging and the record, never read by them."""
