"""A leg's identity at the broker (admin): issue or replace its credentials, revoke them. Audited, never logged: the
password is in the answer once and nowhere else (the broker keeps it hashed)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Annotated

from fastapi import APIRouter, Depends, status
from pydantic import BaseModel

from backend.deps import Admin, Conn, get_settings
from backend.errors import ConflictError
from backend.schemas.devices import DeviceIdPath
from backend.schemas.errors import CONFLICT, FORBIDDEN, UNAUTHORIZED
from backend.settings import Settings
from backend.store import devices as devices_store
from device_bridge.broker_admin import BrokerAdmin, BrokerAdminError

router = APIRouter(prefix="/api/devices", tags=["devices"])


class CredentialsOut(BaseModel):
    device_id: str
    username: str
    password: str
    broker_url: str
    replaced: bool
    words: str


@contextmanager
def _broker(settings: Settings) -> Iterator[BrokerAdmin]:
    if settings.broker_url is None or settings.broker_admin_username is None or settings.broker_admin_password is None:
        raise ConflictError("no broker is configured on this server (QUASITUNE_BROKER_URL and the broker's admin "
                            "identity, QUASITUNE_BROKER_ADMIN_USERNAME / _PASSWORD): leg identities are issued there")
    try:
        admin = BrokerAdmin(settings.broker_url, settings.broker_admin_username,
                            settings.broker_admin_password.get_secret_value(),
                            None if settings.broker_ca_file is None else str(settings.broker_ca_file))
    except (BrokerAdminError, OSError) as exc:
        raise ConflictError(f"the broker could not be reached as its admin: {exc}") from None
    try:
        yield admin
    finally:
        admin.close()


@router.post("/{device_id}/credentials", response_model=CredentialsOut, status_code=status.HTTP_201_CREATED,
             responses={**UNAUTHORIZED, **FORBIDDEN, **CONFLICT})
def issue_credentials(device_id: DeviceIdPath, conn: Conn, user: Admin,
                      settings: Annotated[Settings, Depends(get_settings)]) -> dict:
    """The leg's identity at the broker: issued for a new leg, or replaced (the old password stops working and a bridge
    connected with it is disconnected at once). The password is shown in this answer only: write it into the bridge's
    credentials file (``quasitune bridge --credentials``)."""
    with _broker(settings) as broker:
        try:
            identity, replaced = broker.add_device(device_id), False
        except BrokerAdminError as exc:
            if "already exists" not in str(exc):
                raise ConflictError(str(exc)) from None
            try:      # only a leg's own identity is replaced: never a server's nor the broker's admin
                identity, replaced = broker.replace_device(device_id), True
            except BrokerAdminError as refused:
                raise ConflictError(str(refused)) from None
    devices_store.register_device(conn, device_id, "can", "mqtt", device_id)
    devices_store.record_command(conn, device_id, "credentials_replace" if replaced else "credentials_issue", user)
    return {"device_id": device_id, "username": identity.username, "password": identity.password,
            "broker_url": settings.broker_url, "replaced": replaced,
            "words": ("new credentials; the old ones no longer work" if replaced else "credentials issued") +
                     ": shown once, write them into the leg's bridge credentials file now"}


@router.delete("/{device_id}/credentials", status_code=status.HTTP_204_NO_CONTENT,
               responses={**UNAUTHORIZED, **FORBIDDEN, **CONFLICT})
def revoke_credentials(device_id: DeviceIdPath, conn: Conn, user: Admin,
                       settings: Annotated[Settings, Depends(get_settings)]) -> None:
    """The leg's identity removed at the broker: a bridge connected with it is disconnected now and refused from then
    on (audited). Issue new credentials to let it back."""
    with _broker(settings) as broker:
        try:
            broker.revoke_device(device_id)
        except BrokerAdminError as exc:
            raise ConflictError(str(exc)) from None
    devices_store.record_command(conn, device_id, "credentials_revoke", user)
