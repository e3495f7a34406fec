"""A leg's identity at the broker, from the API (admin): issued once and shown once, replaced and revoked at once,
audited without the password."""

from __future__ import annotations

import json

import can
import pytest

from device_bridge.mqtt_bus import MqttBus
from tests.helpers.api import make_api
from tests.helpers.mosquitto import ADMIN


@pytest.fixture
def broker_api(tmp_path, model, migrated_sqlite, broker):
    api, client = make_api(tmp_path / "broker", lambda: model, template=migrated_sqlite, broker_url=broker.url,
                           broker_admin_username=ADMIN, broker_admin_password=broker.admin_password,
                           broker_ca_file=broker.ca_file)
    with client:
        yield api


def _connect(broker, device_id: str, password: str, timeout_s: float = 5.0) -> MqttBus:
    return MqttBus(device_id, broker.url, device_id, password, role="device", ca_file=broker.ca_file,
                   connect_timeout_s=timeout_s)


def test_an_admin_issues_replaces_and_revokes_a_legs_credentials(broker_api, broker):
    api, url = broker_api, "/api/devices/leg-api-1/credentials"
    first = api.client.post(url, headers=api.as_("admin"))
    assert first.status_code == 201 and not first.json()["replaced"] and "shown once" in first.json()["words"]
    _connect(broker, "leg-api-1", first.json()["password"]).shutdown()          # the bridge gets in with it
    second = api.client.post(url, headers=api.as_("admin"))
    assert second.status_code == 201 and second.json()["replaced"]
    with pytest.raises(can.CanInitializationError):
        _connect(broker, "leg-api-1", first.json()["password"], timeout_s=2)    # the old one is out
    leg = _connect(broker, "leg-api-1", second.json()["password"])
    try:
        assert api.client.delete(url, headers=api.as_("admin")).status_code == 204
        for _ in range(100):
            if not leg.connected:
                break
            leg.recv(0.05)
        assert not leg.connected                                                   # out at once
    finally:
        leg.shutdown()
    audit = api.client.get("/api/audit", headers=api.as_("admin"), params={"entity": "device"}).json()["items"]
    actions = [e["action"] for e in audit]
    assert actions[:3] == ["device.credentials_revoke", "device.credentials_replace", "device.credentials_issue"]
    text = json.dumps(audit)
    assert first.json()["password"] not in text and second.json()["password"] not in text


def test_only_an_admin_may_and_only_with_a_broker(broker_api, api):
    for role in ("prosthetist", "viewer"):
        r = broker_api.client.post("/api/devices/leg-api-2/credentials", headers=broker_api.as_(role))
        assert r.status_code == 403
    r = api.client.post("/api/devices/leg-api-2/credentials", headers=api.as_("admin"))
    assert r.status_code == 409 and "no broker is configured" in r.json()["detail"]
    r = broker_api.client.post("/api/devices/leg%2Fx/credentials", headers=broker_api.as_("admin"))
    assert r.status_code in (404, 422)


def test_only_a_legs_identity_is_issued_replaced_or_revoked_here(broker_api, broker, broker_admin):
    """A server instance's identity and the broker's admin are not legs: replacing one would hand out a server-role
    password (every leg's frames) or cut the running instance off, and the admin's would leave no one able to revoke
    a stolen leg. Each is refused (409) and keeps working."""
    api = broker_api
    server_password = broker_admin.add_server("api-two")
    for name in ("api-two", ADMIN):
        for method in ("post", "delete"):
            r = getattr(api.client, method)(f"/api/devices/{name}/credentials", headers=api.as_("admin"))
            assert r.status_code == 409 and "is not a leg's identity" in r.json()["detail"], (name, method, r.text)
    still = MqttBus("any-leg", broker.url, "api-two", server_password, role="server", ca_file=broker.ca_file)
    still.shutdown()                                                   # the server's password still works
    assert broker_admin.add_device("leg-after") and broker_admin.replace_device("leg-after")   # the admin still can
