"""fem_import — readers of finite-element modal exports.

Role in the data flow (``shared/DESIGN.md``): reads the design office's FE
export (UFF 2411/2412/55, Nastran punch eigenvectors) through a format
registry into FE modes (nodes, elements, frequencies, mass-normalised shapes)
and evaluates shapes at sensor points and directions. It is the first link:
:mod:`ema` pairs against it and :mod:`receptance` builds the hybrid model from
its shapes.
"""
