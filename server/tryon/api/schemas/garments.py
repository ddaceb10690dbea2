"""Response and request schemas for garments."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from tryon.garment.model import GarmentMeta

Category = Literal["top", "bottom", "dress"]
# An upload's category: one of the above, or "auto" to guess it from the file name.
CategoryChoice = Literal["auto", "top", "bottom", "dress"]
CATEGORY_CHOICE_DESCRIPTION = (
    "top | bottom | dress, or auto (the default): guessed from words in the file name, as `tryon ingest` "
    "does: dress, gown, suit... or a top word and a bottom word together (an outfit, several pieces in one "
    "file) make a dress; skirt, trousers, pants, shorts, jeans... a bottom; shirt, tee, top, blouse, "
    "sleeve, jacket... a top. A file name with none of these words is refused (422)."
)
Units = Literal["auto", "m", "cm", "mm", "dm", "in"]
MeshFormat = Literal["json", "glb", "obj"]


class SpringCounts(BaseModel):
    structural: int = Field(ge=0, description="structural springs (count)")
    shear: int = Field(ge=0, description="shear springs (count)")
    bending: int = Field(ge=0, description="bending springs (count)")


class GarmentEntry(BaseModel):
    """A catalogue entry: what a garment is and how it was prepared."""

    id: str = Field(description="catalogue id (hash of the file content and preparation parameters)")
    name: str = Field(description="display name")
    category: Category = Field(description="top | bottom | dress")
    size: str | None = Field(default=None, description="size label, e.g. S, M, L")
    style: str | None = Field(default=None, description="the style (one product in several sizes) this entry is "
                                                        "one size of, a short id such as tshirt; null for none")
    chart: dict[str, list[float]] | None = Field(
        default=None, description="the size's chart row: the body girths it is made for, {chest | waist | hips: "
                                  "[min, max]} cm; null for none")
    units: str = Field(description="units the source file was read in (m, cm, mm, dm, in)")
    units_guessed: bool = Field(description="true if the units were guessed from the garment's size")
    simplification: float = Field(gt=0, le=1, description="simplification degree B = kept / original vertices")
    vertices: int = Field(ge=0, description="vertices of the full mesh")
    faces: int = Field(ge=0, description="triangles of the full mesh")
    coarse_vertices: int = Field(ge=0, description="vertices of the simplified (simulated) mesh")
    coarse_faces: int = Field(ge=0, description="triangles of the simplified mesh")
    springs: SpringCounts = Field(description="springs of the simplified mesh by type")
    source_name: str = Field(description="file name as uploaded")
    notes: list[str] = Field(default_factory=list, description="what loading and cleaning did, in words")
    pieces: list[Category] | None = Field(
        default=None, description="for a file of separate garments worn together (a MakeHuman outfit: a shirt and "
                                  "trousers), each piece's category in the file's order: tried on alone it drapes "
                                  "as its own outfit, and it cannot go in garment_ids with other garments; null "
                                  "for one garment")

    @classmethod
    def from_meta(cls, meta: GarmentMeta, pieces: list[str] | None = None) -> "GarmentEntry":
        return cls(
            id=meta.id, name=meta.name, category=meta.category, size=meta.size, style=meta.style,
            chart=meta.chart, units=meta.units,
            units_guessed=meta.units_guessed, simplification=meta.simplification, vertices=meta.vertices,
            faces=meta.faces, coarse_vertices=meta.coarse_vertices, coarse_faces=meta.coarse_faces,
            springs=SpringCounts(**{k: meta.springs.get(k, 0) for k in ("structural", "shear", "bending")}),
            source_name=meta.source_name, notes=list(meta.notes), pieces=pieces,
        )


class GarmentList(BaseModel):
    garments: list[GarmentEntry] = Field(description="every catalogue entry, oldest first")


SIZE_CHART_DESCRIPTION = (
    'the size\'s chart row as JSON, body girths in cm: {"chest": [92, 100], "waist": [78, 86], "hips": 100} '
    "(chest, waist, hips, each [min, max] or one value, within the range a body may measure); needs a size"
)


class StyleSize(BaseModel):
    size: str = Field(description="size label")
    garment_id: str = Field(description="catalogue id of this size (GET /api/garments/{id})")
    chart: dict[str, list[float]] | None = Field(description="its chart row, {girth: [min, max]} cm, or null")


class StyleOut(BaseModel):
    """A style: one product in several sizes, the sizes in order (smallest first)."""

    style: str = Field(description="style id")
    name: str = Field(description="display name (its entries' name without the size label)")
    category: Category = Field(description="top | bottom | dress")
    sizes: list[StyleSize] = Field(description="the sizes in order")
