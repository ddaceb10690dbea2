"""Garment preparation, offline (SPEC section 3): from a mesh file to a cached ``GarmentModel``.

``ingest`` (load, weld, clean, orient, units) -> ``simplify`` (triangle collapse, re-attachment) ->
``springs`` (structural, shear, bending on the coarse mesh) -> ``prepare`` (masses, the model) ->
``catalogue`` (SQLite index + arrays on disk). ``generate`` builds the catalogue's own garments.
"""
