"""Judging a run: was it good. Metrics, the requirements and their pointing
indices, ensembles, the verdict in words, the law's telemetry summary and
the comparison of laws. Reads the record, never the presenting."""
