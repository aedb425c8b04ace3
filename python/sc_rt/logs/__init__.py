"""The run's log: the strict ``lcm-logger`` reader, decoding, the run rebuilt from it, ``sc-rt report``
and ``sc-rt replay``."""
