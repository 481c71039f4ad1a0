"""`hdsense fleet`: gear-health trends over many joints and many hours, on Dask
(docs/results/fleet.md)."""
