"""Scripts copied into every run's output folder: ``crazyswarm2/fly.py`` and ``crazyflie/cflib_upload.py``.

They run on the computer that talks to the Crazyflies, from the run's folder, and read
its ``trajectories/``, ``crazyswarm2/crazyflies.yaml`` and ``crazyflie/compressed.json``.
"""
