"""ema — experimental modal analysis of impact-hammer tests.

Role in the data flow (``shared/DESIGN.md``): reads the lab's hammer-test
files (UFF58 time histories + channel table), screens hits, estimates H1/H2
FRFs and coherence, identifies modes by LSCE with a stabilisation diagram and
LSFD shapes, merges the setups' mode lists and pairs the experimental modes
with the FE modes of :mod:`fem_import` by MAC. Its output (a mode set and the
measured FRFs) feeds :mod:`receptance`.
"""
