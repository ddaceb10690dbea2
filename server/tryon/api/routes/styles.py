"""``GET /api/styles``: the catalogue's styles (one product in several sizes), each with its sizes in order."""

from __future__ import annotations

from fastapi import APIRouter

from tryon.api.deps import CatalogueDep
from tryon.api.schemas.garments import StyleOut, StyleSize
from tryon.garment.model import GarmentMeta

router = APIRouter(tags=["styles"])


def style_name(entries: list[GarmentMeta]) -> str:
    """A style's display name: its first size's name without the size label at its end ("T-shirt S" ->
    "T-shirt")."""
    first = entries[0]
    suffix = f" {first.size}" if first.size else ""
    return first.name[: -len(suffix)] if suffix and first.name.endswith(suffix) else first.name


def style_out(style: str, entries: list[GarmentMeta]) -> StyleOut:
    """The answer for one style (``Catalogue.style``: its entries in size order)."""
    return StyleOut(style=style, name=style_name(entries), category=entries[0].category,
                    sizes=[StyleSize(size=m.size, garment_id=m.id, chart=m.chart) for m in entries])


@router.get("/styles", response_model=list[StyleOut])
def list_styles(catalogue: CatalogueDep) -> list[StyleOut]:
    """Every style with its sizes in order (smallest first) and each size's chart row, in the order the
    styles were added; entries without a style are not listed here (GET /api/garments lists them)."""
    return [style_out(style, entries) for style, entries in catalogue.styles().items()]
