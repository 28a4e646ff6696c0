"""Many videos at once: one video per task on Dask, a manifest, a combined table."""
