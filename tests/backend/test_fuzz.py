"""schemathesis over the whole OpenAPI schema: no input makes a 5xx."""

from __future__ import annotations

import atexit
import itertools
import tempfile
from concurrent.futures import Future
from pathlib import Path

import pytest
import schemathesis
from hypothesis import HealthCheck, given, settings
from schemathesis.checks import positive_data_acceptance

from tests.helpers.api import make_api

_tmp = tempfile.TemporaryDirectory(prefix="quasitune-fuzz-")
# removed when the process ends, not when the module's fixture ends: under --dist worksteal a worker may set the
# fixture up again for the operations it takes later, and the app's database must still be there
atexit.register(_tmp.cleanup)
_setups = itertools.count(1)
# the app is built when the file is collected (schemathesis reads its schema then; its fixture-based loader does not
# run under pytest 9); its model is the run's own, handed over when the test starts, so collecting costs no model load
_model: Future = Future()
_api, _client = make_api(Path(_tmp.name), _model.result)


schema = schemathesis.openapi.from_asgi("/openapi.json", _client.app)


@pytest.fixture(scope="module")
def fuzz_api(model):
    if not _model.done():
        _model.set_result(model)
    with _client:
        patient = _api.new_patient(f"FUZZ-{next(_setups)}")      # set up again by a worker: a patient of its own
        first = _api.propose(patient["id"])
        _api.client.post(f"/api/proposals/{first['id']}/edits", headers=_api.as_("prosthetist"), json={
            "rows": [{"joint": "knee", "subphase": "swing_flexion", "b_Nm_s_per_rad": 1.0}], "comment": "seed"})
        yield _api


# one test per operation, by its label: schemathesis's own parametrize gives all 58 items one node id under pytest 9,
# and pytest-xdist (scripts/test.sh runs this file in one of two processes) would run only one of them
OPERATIONS = [result.ok() for result in schema.get_all_operations()]


@pytest.mark.parametrize("operation", OPERATIONS, ids=[op.label for op in OPERATIONS])
def test_no_input_breaks_the_api(operation, fuzz_api):
    # positive_data_acceptance is left out on purpose: schema-valid tables can still break a safety limit, and an
    # edit that changes nothing is refused; those 422s are the design, not a bug. Every other default check runs.
    @settings(max_examples=40, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
    @given(case=operation.as_strategy())
    def check(case) -> None:
        case.call_and_validate(headers=fuzz_api.as_("prosthetist"), excluded_checks=[positive_data_acceptance])

    check()
