"""The plant emulator process (``sc-rt emulator``): receiver, publisher, plant twin, sensors, peers and its loop."""
