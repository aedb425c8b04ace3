"""The wire: LCM transport, message codecs, the .lcm definitions as data, JSON and authentication.

Codec and transport only: no run policy, no results."""
