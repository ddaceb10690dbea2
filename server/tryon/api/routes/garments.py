"""Routes for garments: the catalogue (list, one entry, its mesh) and admin writes (upload, change its words,
delete)."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, File, Form, HTTPException, Query, Response, UploadFile, status
from fastapi.concurrency import run_in_threadpool

from tryon.api.deps import AdminDep, CatalogueDep, SettingsDep
from tryon.api.export import MEDIA_TYPES, json_bytes, mesh_bytes, mesh_json
from tryon.api.outfits import file_pieces
from tryon.api.schemas.garments import (CATEGORY_CHOICE_DESCRIPTION, FABRIC_DESCRIPTION, FABRIC_MAX_CHARS,
                                        SIZE_CHART_DESCRIPTION, CategoryChoice, GarmentEntry, GarmentList,
                                        GarmentPatch, MeshFormat, Units)
from tryon.garment.catalogue import Catalogue, check_fabric, resolve_category
from tryon.garment.ingest import GarmentError, file_extension
from tryon.garment.model import GarmentMeta
from tryon.garment.prepare import DEFAULT_SIMPLIFICATION
from tryon.garment.sizes import check_labels

router = APIRouter(tags=["garments"])

# Uploads are read in chunks of this many bytes so that an oversized one is refused without holding it.
UPLOAD_CHUNK = 1 << 20


def _entry(catalogue: Catalogue, meta: GarmentMeta) -> GarmentEntry:
    """A catalogue entry as the API gives it, with its pieces if it is a file of separate garments."""
    return GarmentEntry.from_meta(meta, pieces=file_pieces(catalogue, meta.id))


def _not_found(garment_id: str) -> HTTPException:
    return HTTPException(status.HTTP_404_NOT_FOUND, f"no garment with id {garment_id!r}")


@router.get("/garments", response_model=GarmentList)
def list_garments(catalogue: CatalogueDep) -> GarmentList:
    """The catalogue: every entry with counts (original and simplified), size and units."""
    return GarmentList(garments=[_entry(catalogue, m) for m in catalogue.list()])


@router.get("/garments/{garment_id}", response_model=GarmentEntry)
def get_garment(garment_id: str, catalogue: CatalogueDep) -> GarmentEntry:
    meta = catalogue.get(garment_id)
    if meta is None:
        raise _not_found(garment_id)
    return _entry(catalogue, meta)


@router.get("/garments/{garment_id}/mesh")
async def garment_mesh(
    garment_id: str,
    catalogue: CatalogueDep,
    format: Annotated[MeshFormat, Query(description="json | glb | obj")] = "json",
    level: Annotated[Literal["full", "coarse"], Query(description="full mesh, or the simplified one")] = "full",
) -> Response:
    """The garment's rest mesh in metres, y up: JSON ``{"vertices", "faces"}``, GLB or OBJ."""
    if catalogue.get(garment_id) is None:
        raise _not_found(garment_id)
    model = await run_in_threadpool(catalogue.model, garment_id)
    if level == "full":
        vertices, faces = model.vertices, model.faces
    else:
        vertices, faces = model.coarse_vertices, model.coarse_faces
    if format == "json":
        return Response(content=json_bytes(mesh_json(vertices, faces)), media_type=MEDIA_TYPES["json"])
    data = await run_in_threadpool(mesh_bytes, vertices, faces, format)
    return Response(content=data, media_type=MEDIA_TYPES[format],
                    headers={"Content-Disposition": f'inline; filename="{garment_id}.{format}"'})


@router.post("/garments", response_model=GarmentEntry, status_code=status.HTTP_201_CREATED,
             responses={200: {"description": "the same file with the same parameters was already there"},
                        409: {"description": "the same file is already in as another category, under another "
                                             "name, or with another fabric, style, size or chart: change its words "
                                             "with PATCH"}})
async def upload_garment(
    _: AdminDep,
    settings: SettingsDep,
    catalogue: CatalogueDep,
    response: Response,
    file: Annotated[UploadFile, File(description="the mesh file: .obj, .glb, .gltf, .ply, .stl or .off")],
    name: Annotated[str, Form(min_length=1, max_length=200, description="display name")],
    category: Annotated[CategoryChoice, Form(description=CATEGORY_CHOICE_DESCRIPTION)] = "auto",
    units: Annotated[Units, Form(description="units of the file's coordinates, or auto to guess")] = "auto",
    size: Annotated[str | None, Form(max_length=20, description="size label, e.g. M")] = None,
    style: Annotated[str | None, Form(max_length=40, description="style id: the product this file is one size "
                                                                 "of, e.g. tshirt (needs a size)")] = None,
    size_chart: Annotated[str | None, Form(max_length=2000, description=SIZE_CHART_DESCRIPTION)] = None,
    fabric: Annotated[str | None, Form(max_length=FABRIC_MAX_CHARS, description=FABRIC_DESCRIPTION)] = None,
    simplify: Annotated[float, Form(ge=0.05, le=1.0, allow_inf_nan=False,
                                    description="simplification degree B (kept / original vertices)")]
    = DEFAULT_SIMPLIFICATION,
) -> GarmentEntry:
    """Prepare an uploaded garment into the catalogue (admin). 201 with the new entry; 200 with the
    existing one if the same file was already ingested with the same parameters and words; 409 if it is
    in under another name (or fabric, style, size, chart): PATCH changes those. A refused file is a 4xx with the
    reason in words; the catalogue is then as it was."""
    name, size = name.strip(), (size or "").strip() or None
    if not name:
        raise HTTPException(422, "name: must not be blank")
    filename = file.filename or ""
    try:
        file_extension(filename)
    except GarmentError as exc:
        raise HTTPException(exc.status, f"file: {exc}") from None
    try:
        category = resolve_category(category, filename)
    except GarmentError as exc:
        raise HTTPException(exc.status, f"category: {exc}") from None
    try:
        style, size, chart = check_labels(style, size, size_chart)
    except GarmentError as exc:
        raise HTTPException(exc.status, str(exc)) from None
    fabric = (fabric or "").strip() or None
    try:
        check_fabric(fabric, category)
    except GarmentError as exc:
        raise HTTPException(exc.status, f"fabric: {exc}") from None
    data = bytearray()
    while chunk := await file.read(UPLOAD_CHUNK):
        data += chunk
        if len(data) > settings.max_upload_bytes:
            raise HTTPException(413,
                                f"file: larger than the limit of {settings.max_upload_bytes:,} bytes")
    try:
        meta, created = await run_in_threadpool(
            catalogue.ingest_with_status, bytes(data), name, category, units, simplify, size, filename,
            max_faces=settings.max_faces, style=style, chart=chart, fabric=fabric, same_words=True,
        )
    except GarmentError as exc:
        raise HTTPException(exc.status, f"{exc.field}: {exc}") from None
    if not created:
        response.status_code = status.HTTP_200_OK
    return await run_in_threadpool(_entry, catalogue, meta)


@router.patch("/garments/{garment_id}", response_model=GarmentEntry)
async def change_garment(_: AdminDep, garment_id: str, changes: GarmentPatch, catalogue: CatalogueDep) -> GarmentEntry:
    """Change an entry's name, size, style, chart or fabric (admin): a JSON object of the fields to change (null
    removes a size, style or chart; a fabric of null is the category's). Checked as an upload's words are; 200
    with the changed entry, 404 for an unknown id, 409 if the style already has that size, 422 naming the field;
    a refusal changes nothing. Another fabric: an entry whose masses were its old fabric's density takes the new
    one's, its stored models' masses rescaled by the ratio; the id stays. The file, its category and the rest of
    its preparation stay: to change those, delete the entry and upload again."""
    try:
        meta = await run_in_threadpool(catalogue.update, garment_id, **changes.words())
    except GarmentError as exc:
        raise HTTPException(exc.status, f"{exc.field}: {exc}") from None
    if meta is None:
        raise _not_found(garment_id)
    return await run_in_threadpool(_entry, catalogue, meta)


@router.delete("/garments/{garment_id}", status_code=status.HTTP_204_NO_CONTENT)
async def delete_garment(_: AdminDep, garment_id: str, catalogue: CatalogueDep) -> Response:
    """Remove an entry and its prepared files (admin)."""
    if not await run_in_threadpool(catalogue.delete, garment_id):
        raise _not_found(garment_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
