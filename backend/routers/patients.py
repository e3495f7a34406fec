"""Patients: list, create, read, update."""

from __future__ import annotations

from fastapi import APIRouter, status

from backend.deps import Conn, CurrentUser, Prosthetist
from backend.schemas.common import IdPath
from backend.schemas.errors import CONFLICT, FORBIDDEN, NOT_FOUND, UNAUTHORIZED
from backend.schemas.patients import PatientCreate, PatientOut, PatientPatch
from backend.store import patients

router = APIRouter(prefix="/api/patients", tags=["patients"], responses=UNAUTHORIZED)


@router.get("", response_model=list[PatientOut])
def list_patients(conn: Conn, _user: CurrentUser) -> list[dict]:
    """Every patient, by code name."""
    return patients.list_patients(conn)


@router.post("", response_model=PatientOut, status_code=status.HTTP_201_CREATED,
             responses={**FORBIDDEN, **CONFLICT})
def create_patient(body: PatientCreate, conn: Conn, user: Prosthetist) -> dict:
    """Register a patient (prosthetist)."""
    return patients.create_patient(conn, body.fields(), user)


@router.get("/{patient_id}", response_model=PatientOut, responses=NOT_FOUND)
def get_patient(patient_id: IdPath, conn: Conn, _user: CurrentUser) -> dict:
    return patients.get_patient(conn, patient_id)


@router.patch("/{patient_id}", response_model=PatientOut,
              responses={**FORBIDDEN, **NOT_FOUND, **CONFLICT})
def update_patient(patient_id: IdPath, body: PatientPatch, conn: Conn, user: Prosthetist) -> dict:
    """Change some of a patient's fields (prosthetist); the audit log keeps the values before and after."""
    return patients.update_patient(conn, patient_id, body.changes(), user)
