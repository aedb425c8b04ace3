"""``sc-rt export``: a log to MCAP for Foxglove and PlotJuggler."""
