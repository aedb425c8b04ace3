"""Live tools on a bus: ``sc-rt spy``, ``sc-rt lcm-spy``, ``sc-rt fault``."""
