"""The per-table readers of a scenario file, one module per table or group of
tables (docs/SCENARIOS.md): ``[spacecraft]``, ``[disturbance]`` and
``[[faults]]`` (spacecraft.py), ``[guidance]`` (guidance.py; its reference files, reference_file.py), ``[laws.NAME]``
(laws.py), ``[wheels]`` (wheels.py), ``[orbit]`` and ``[environment]``
(orbit.py), ``[magnetorquers]`` (magnetorquers.py), ``[momentum]`` and
``[bdot]`` (momentum.py), ``[sensors]`` and the estimator (sensors.py),
``[sensors.magnetometer]`` (magnetometer.py), ``[[requirements]]`` (requirements.py). Each reads and checks its table
with the schema machinery of sc_rt.scenario.schema; sc_rt.scenario.reader
puts the tables together into a ``Scenario``."""
