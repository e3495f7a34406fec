"""Experiments that need the learning model: the bench's reference at a task, walks and the controller comparison,
the dashboard's simulated preview, the leave-one-condition-out evaluation and the proposal figure.

This is the one place that composes the model (``controller_core``) with the simulated leg
(``device_bridge.sim``); the leg's own code never imports the model.
"""
