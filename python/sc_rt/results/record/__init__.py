"""The run record: what happened. ``Run`` and its declared fields, ``RunMeta``,
the chunked on-disk store, JSON that stays JSON. Reads nothing of judging
or presenting (pyproject.toml's import contract)."""
