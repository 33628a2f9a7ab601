"""Numba's disk cache for launchers that inline bodies from other files.

`cache=True` keys a compiled launcher on its own file's (mtime, size) only, so an edit to a body it
inlines would be missed. `depend_on(dispatchers, files)` stamps each launcher's cache index with
(the newest mtime, the summed size) of all the files it inlines: editing any of them recompiles."""

import os


def depend_on(dispatchers, files) -> None:
    stats = [os.stat(f) for f in files]
    stamp = (max(s.st_mtime for s in stats), sum(s.st_size for s in stats))
    for d in dispatchers:
        cache_file = getattr(getattr(d, "_cache", None), "_cache_file", None)
        if cache_file is not None and hasattr(cache_file, "_source_stamp"):
            cache_file._source_stamp = stamp
