"""The jobs a user runs: identify, select, compare, the suite, and the store that keeps
every finished run.

The functions are importable from :mod:`flexid` (``flexid.identify``, ``flexid.select``,
``flexid.compare``); :mod:`flexid.jobs.suite`, :mod:`flexid.jobs.store`,
:mod:`flexid.jobs.statistics` and :mod:`flexid.jobs.progress` are public modules.
"""

__all__: list[str] = []
