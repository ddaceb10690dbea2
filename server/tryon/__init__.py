"""Virtual try-on service: measurements -> body; mesh file -> garment model; body + model -> drape.

Stages (one sub-package each, data flows one way): ``body`` -> ``garment`` -> ``sim`` -> ``api``;
``cli`` is a thin command line over the same functions.
"""

__version__ = "0.1.0"
