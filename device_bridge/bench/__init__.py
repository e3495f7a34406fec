"""The bench with a controller on it: the learning model composed with the simulated leg.

The one place below the backend where the model (``controller_core.model``) meets the simulated leg
(``device_bridge.sim``): the reference a walk is scored against at any task, the one controller factory, walks at one
task or over a course, and the one comparison of two walks. The leg's own code (firmware, node, host, the simulated
plant) never imports the model. The product (``backend.bench``: previews) and the lab (``lab``: evaluation and
comparisons) both build on this package.
"""
