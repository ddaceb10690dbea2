"""``GET /api/fabrics``: the fabrics a garment may be made of, with their measured figures and source."""

from __future__ import annotations

from fastapi import APIRouter

from tryon.api.schemas.garments import FabricList, FabricOut
from tryon.garment.fabric import DEFAULT_FABRIC, FABRICS

router = APIRouter(tags=["garments"])


@router.get("/fabrics", response_model=FabricList)
def list_fabrics() -> FabricList:
    """Every fabric (a name an upload's or a PATCH's ``fabric`` takes) with its areal density (kg/m^2), stretch and
    shear stiffness (N/m), bending stiffness (N m) and where the figures come from; and each category's default."""
    return FabricList(fabrics=[FabricOut.of(f) for f in FABRICS.values()], defaults=dict(DEFAULT_FABRIC))
