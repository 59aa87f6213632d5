"""Bounds of the identification that callers check before any work (kept apart: importing it is free)."""

#: Largest LSCE order :func:`ema.identify.identify` accepts (poles in the band; the thesis band holds a few
#: dozen modes; order 100 takes 4 s, 200 9 s, 300 24 s on the virtual lab's 29 channels: the cost grows steeply).
MAX_ORDER = 300
