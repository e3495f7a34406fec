"""Between the routers and storage: the rules and the views of a patient's parameter versions.

Storage (:mod:`backend.store`) writes and reads rows and proves stored content by its hash; it decides nothing. Here
a version is checked as the device will run it when it is created or edited (:mod:`device_bridge.as_run`), re-checked
and gated on the bench's verdict when it is approved (:mod:`backend.services.decisions`,
:mod:`backend.services.bench_verdict`), and shown as the page and the API show it (its table or nodes, the live
check, clinical words). ``tests/test_layering.py`` holds storage to that.
"""
