"""Response and request schemas for garments."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator
from pydantic_core import PydanticCustomError

from tryon.body.params import MEASUREMENT_RANGES
from tryon.garment.catalogue import NAME_MAX_CHARS, WORDS, check_fabric
from tryon.garment.fabric import DEFAULT_FABRIC, FABRICS, Fabric
from tryon.garment.ingest import GarmentError
from tryon.garment.model import GarmentMeta
from tryon.garment.sizes import CHART_KEYS, SIZE_MAX_CHARS, check_size, check_style, parse_chart

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
# Longest fabric name taken (the names are short ids such as cotton-twill).
FABRIC_MAX_CHARS = 40
FABRIC_DESCRIPTION = (
    f"what the garment is made of: {', '.join(FABRICS)} (GET /api/fabrics: each one's weight and stiffness); "
    "default: its category's (" + ", ".join(f"{c} {f}" for c, f in DEFAULT_FABRIC.items()) + "). Its masses are "
    "made of the fabric's density"
)


class FabricOut(BaseModel):
    """A fabric: its measured weight and stiffness (``garment/fabric.py``), SI units."""

    name: str = Field(description="the fabric's name, as an upload or a PATCH gives it")
    density: float = Field(gt=0, description="areal density, kg/m^2 (x 1000: g/m^2)")
    stretch: float = Field(gt=0, description="stretch stiffness, N/m (force per unit width per unit strain; the "
                                             "mean of warp and weft)")
    shear: float = Field(gt=0, description="shear stiffness, N/m")
    bending: float = Field(ge=0, description="bending stiffness, N m (recorded with the measurement; the springs' "
                                             "bending does not read it)")
    source: str = Field(description="where the figures come from")

    @classmethod
    def of(cls, fabric: Fabric) -> "FabricOut":
        """``fabric``'s figures to 6 significant digits (a mean of warp and weft reads 51.07, not 51.06999999999999)."""
        figure = lambda x: float(f"{x:.6g}")  # noqa: E731
        return cls(name=fabric.name, density=figure(fabric.density), stretch=figure(fabric.stretch),
                   shear=figure(fabric.shear), bending=figure(fabric.bending), source=fabric.source)


class FabricList(BaseModel):
    """``GET /api/fabrics``: every fabric a garment may be made of, and each category's default."""

    fabrics: list[FabricOut] = Field(description="every fabric, with its figures")
    defaults: dict[Category, str] = Field(description="the fabric of a garment that names none, by category")


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
    fabric: str = Field(description="what it is made of (a name of GET /api/fabrics): the one given at upload, or "
                                    "its category's; PATCH changes it")
    fabric_figures: FabricOut = Field(description="that fabric's weight (kg/m^2) and stiffness (N/m)")
    density: float = Field(gt=0, description="areal density of its masses, kg/m^2: its fabric's, unless the "
                                             "ingestion gave one (tryon ingest --density)")
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
        fabric = check_fabric(meta.fabric, meta.category)
        return cls(
            id=meta.id, name=meta.name, category=meta.category, size=meta.size, style=meta.style,
            chart=meta.chart, fabric=fabric.name, fabric_figures=FabricOut.of(fabric),
            density=meta.density or fabric.density, units=meta.units,
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


def _refused(exc: GarmentError) -> PydanticCustomError:
    """A catalogue check's refusal as a validation error in its own words (no "Value error, " in front)."""
    return PydanticCustomError("garment_words", str(exc))


# Fields an entry has that a PATCH cannot change, and why.
_FIXED_FIELDS = {
    "category": "category cannot be changed: it decides how the file is put on the body; delete the entry and "
                "upload the file again as the other category",
    **{f: f"{f} cannot be changed: it is part of how the file was prepared (the entry's id); upload the file "
          f"again with the {f} you want" for f in ("units", "simplify", "simplification")},
    "density": "density cannot be changed on its own: an entry's masses are made of its fabric's density; PATCH "
               "its fabric (GET /api/fabrics lists them)",
}


class ChartRowIn(BaseModel):
    """A size-chart row: the body girths (cm) the size is made for, each one value or [min, max]."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    chest: tuple[float, float] | None = Field(
        None, description=f"chest girth, cm, [min, max] or one value, within {list(MEASUREMENT_RANGES['chest'])}")
    waist: tuple[float, float] | None = Field(
        None, description=f"waist girth, cm, [min, max] or one value, within {list(MEASUREMENT_RANGES['waist'])}")
    hips: tuple[float, float] | None = Field(
        None, description=f"hip girth, cm, [min, max] or one value, within {list(MEASUREMENT_RANGES['hips'])}")


class GarmentPatch(BaseModel):
    """``PATCH /api/garments/{id}``: an entry's own words, each optional (absent: unchanged). ``size``,
    ``style`` and ``chart`` may be null (removed); checked as an upload's are: a style needs a size, a chart
    row a size, a style's sizes are each once."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    name: str | None = Field(None, min_length=1, max_length=NAME_MAX_CHARS, description="display name")
    size: str | None = Field(None, max_length=SIZE_MAX_CHARS, description="size label, e.g. M; null: none")
    style: str | None = Field(None, max_length=40, description="style id (a short id such as tshirt: the product "
                                                               "this entry is one size of); null: none")
    chart: ChartRowIn | None = Field(None, description='the size\'s chart row, cm: {"chest": [92, 100], "waist": '
                                                       f'80}} (any of {", ".join(CHART_KEYS)}); null: none')
    fabric: str | None = Field(None, max_length=FABRIC_MAX_CHARS,
                               description=f"{FABRIC_DESCRIPTION}; null: the category's. An entry whose masses "
                                           "were its old fabric's density takes the new one's (the masses rescaled)")

    @model_validator(mode="before")
    @classmethod
    def _known_fields(cls, data: Any) -> Any:
        if isinstance(data, dict):
            for key in data:
                if key in _FIXED_FIELDS:
                    raise PydanticCustomError("fixed_field", _FIXED_FIELDS[key])
                if key not in WORDS:
                    raise PydanticCustomError("unknown_field", "unknown field {key}: a PATCH changes "
                                              f"{', '.join(WORDS)}", {"key": repr(key)[:60]})
            if not data:
                raise PydanticCustomError("nothing_to_change", f"nothing to change: give any of {', '.join(WORDS)}")
        return data

    @field_validator("name", mode="before")
    @classmethod
    def _name(cls, value: Any) -> Any:
        if value is None:
            raise PydanticCustomError("name_needed", "an entry needs a name: it cannot be removed")
        if isinstance(value, str) and not value.strip():
            raise PydanticCustomError("name_blank", "must not be blank")
        return value.strip() if isinstance(value, str) else value

    @field_validator("size", "style", mode="before")
    @classmethod
    def _label(cls, value: Any, info: ValidationInfo) -> Any:
        """A size or style label, checked as an upload checks it."""
        check = check_size if info.field_name == "size" else check_style
        try:
            return check(value) if isinstance(value, str) else value
        except GarmentError as exc:
            raise _refused(exc) from None

    @field_validator("fabric", mode="before")
    @classmethod
    def _fabric(cls, value: Any) -> Any:
        if isinstance(value, str):
            if not value.strip():
                raise PydanticCustomError("fabric_blank", f"must not be blank: give one of {', '.join(FABRICS)}, or "
                                          "null for the category's")
            try:
                return check_fabric(value, "top").name  # a name given: the same whatever the category
            except GarmentError as exc:
                raise _refused(exc) from None
        return value

    @field_validator("chart", mode="before")
    @classmethod
    def _chart(cls, value: Any) -> Any:
        """Our words for a chart row's problems (unknown key, min over max, out of range); the row as
        ``{girth: [min, max]}``, or None for an empty one."""
        if value is None:
            return value
        if not isinstance(value, dict):
            kind = ("true or false" if isinstance(value, bool) else "a number" if isinstance(value, (int, float))
                    else "a string" if isinstance(value, str) else "a list")
            raise PydanticCustomError("chart_object", 'a size chart row is a JSON object such as {"chest": [92, 100], '
                                      f'"waist": 80}} (cm), not {kind}')
        try:
            return parse_chart(value)
        except GarmentError as exc:
            raise _refused(exc) from None

    def words(self) -> dict:
        """The words given, as ``Catalogue.update`` takes them (a chart as ``{girth: [min, max]}``)."""
        out = {key: getattr(self, key) for key in self.model_fields_set}
        if "chart" in out and out["chart"] is not None:
            out["chart"] = {k: list(v) for k, v in out["chart"].model_dump(exclude_none=True).items()}
        return out
