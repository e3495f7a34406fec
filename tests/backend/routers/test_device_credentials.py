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
    return MqttBus(device_id, broker.url, f"device-{device_id}", password, role="device", ca_file=broker.ca_file,
                   connect_timeout_s=timeout_s)


def test_an_admin_issues_replaces_and_revokes_a_legs_credentials(broker_api, broker):
    api, url = broker_api, "/api/devices/leg-api-1/credentials"
    first = api.client.post(url, headers=api.as_("admin"))
    assert first.status_code == 201 and not first.json()["replaced"] and "shown once" in first.json()["words"]
    assert first.json()["username"] == "device-leg-api-1"                        # in the legs' namespace
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


def test_a_legs_credentials_never_touch_a_servers_or_the_admins_identity(broker_api, broker, broker_admin):
    """Legs have a namespace of their own (``device-…``): credentials issued for a device id spelled like a server's
    name or the broker's admin make a new leg identity beside it, never a server-role password (every leg's frames),
    never cutting the running instance off, never leaving no one able to revoke a stolen leg. Replacing or revoking an
    identity that is not a leg's (made without its own role) is refused (409) and changes nothing."""
    api = broker_api
    server = broker_admin.add_server("api-two")
    for name in ("api-two", "server-api-two", ADMIN):
        r = api.client.post(f"/api/devices/{name}/credentials", headers=api.as_("admin"))
        assert r.status_code == 201 and r.json()["username"] == f"device-{name}", r.text
        far = _connect(broker, name, r.json()["password"])
        try:
            assert far.connected
        finally:
            far.shutdown()
    MqttBus("any-leg", broker.url, *server, role="server", ca_file=broker.ca_file).shutdown()   # still works
    MqttBus("any-leg", broker.url, ADMIN, broker.admin_password, role="server", ca_file=broker.ca_file).shutdown()
    broker_admin._command("createClient", username="device-not-a-leg", password="x" * 24)   # no leg role
    for method in ("post", "delete"):
        r = getattr(api.client, method)("/api/devices/not-a-leg/credentials", headers=api.as_("admin"))
        assert r.status_code == 409 and "is not a leg's identity" in r.json()["detail"], (method, r.text)
    got = broker_admin._command("getClient", username="device-not-a-leg")["data"]["client"]
    assert got.get("disabled") is not True and got.get("roles", []) == []               # left as it was
    assert broker_admin.add_device("leg-after") and broker_admin.replace_device("leg-after")   # the admin still can


def test_a_refused_identity_leaves_no_role_behind(broker_admin):
    """Issuing an identity that exists is refused whole: the leg's role made for it is removed again."""
    from device_bridge.broker_admin import BrokerAdminError, device_role

    broker_admin._command("createClient", username="device-taken", password="x" * 24)
    with pytest.raises(BrokerAdminError, match="createClient"):
        broker_admin.add_device("taken")
    with pytest.raises(BrokerAdminError, match="getRole"):
        broker_admin._command("getRole", rolename=device_role("taken"))
