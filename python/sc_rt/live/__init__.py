"""``sc-rt live``: the bus of a run served to Foxglove (and PlotJuggler) as
it happens, with the topics, schemas and derived channels of the MCAP
export (docs/LOGS.md, "Live")."""
