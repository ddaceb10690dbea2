"""Past one machine: the batch work (garment preparation, fit tables) on a Ray cluster. The same plain
functions as the local path run as Ray tasks; Ray is the optional extra ``scale``."""
