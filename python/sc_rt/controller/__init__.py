"""The Python controller process (``sc-rt controller --law module:Class``)."""
