"""Exporters for real clients, one module each, each through the client's own library.

- :mod:`~mrfswarm.export.cflib_`: a Crazyflie's trajectory memory (raw and compressed
  pieces), packed by Bitcraze's ``cflib``, decoded back and evaluated as the firmware does;
- :mod:`~mrfswarm.export.crazyflie_memory`: what each robot's pieces take in that memory and
  whether the compressed flight is still certified (the ``crazyflie`` section of
  ``result.json``);
- :mod:`~mrfswarm.export.crazyswarm2`: Crazyswarm2's ``crazyflies.yaml`` and the flight
  scripts (``mrfswarm/export/scripts/``) copied beside it.
"""
