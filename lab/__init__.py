"""The lab: evaluations, comparisons and figures that judge the model and the controllers, apart from the product.

It may import the model (``controller_core``) and the bench (``device_bridge``, ``device_bridge.bench``), never the
backend: nothing the API serves depends on it. Its commands are offered under ``quasitune`` (``evaluate``,
``compare``, ``plot``) by ``backend.cli``, the one module of the backend that imports it.
"""
