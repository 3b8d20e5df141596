"""The routes that tell about the service: the scene JSON Schema it takes, and a worker's health and counters."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request

from schemas import json_schema

router = APIRouter()


@router.get("/schema", summary="The scene JSON Schema (Draft 2020-12)")
def schema() -> dict[str, Any]:
    return json_schema()


@router.get("/healthz", summary="Liveness and counters")
async def healthz(request: Request) -> dict[str, Any]:  # on the loop: never queued behind pool threads
    return {"status": "ok", **request.app.state.service.status()}
