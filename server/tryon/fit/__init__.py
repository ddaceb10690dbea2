"""Size advice over a style's sizes (issue 27): the ease measured on a drape (``ease``), a size's verdict and
the recommendation (``verdict``), which sizes to drape and each size's answer (``advice``). Data flows
sim -> fit -> api: this package never imports the service."""
