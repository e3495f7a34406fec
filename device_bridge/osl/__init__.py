"""The leg side on an Open Source Leg: QuasiTune's firmware driving the OSL's actuators and sensors through the
``opensourceleg`` SDK (issue 54).

* :mod:`~device_bridge.osl.config`: the leg's configuration file (actuators, joint maps, load cell, rate, link).
* :mod:`~device_bridge.osl.leg`: :class:`~device_bridge.osl.leg.OSLLeg`, a leg to the device stack (``sample()``,
  ``step()``: the seam the simulated leg uses) over SDK objects.
* :mod:`~device_bridge.osl.calibration`: joint zeros and directions, the load cell's zero and sign, each refused
  when it cannot be right.
* :mod:`~device_bridge.osl.loop`: the control loop on the leg's clock, its overruns counted.
* :mod:`~device_bridge.osl.bench_sdk`: SDK subclasses backed by the MuJoCo bench, so the OSL leg walks the bench
  through the SDK's own interfaces (the SDK has no simulation; these are ours).

Nothing here imports the SDK, the model or the server at module level except :mod:`bench_sdk` (SDK and MuJoCo): the
leg's computer installs only ``.[leg]``.
"""
