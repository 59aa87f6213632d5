"""estimator — rail irregularity estimation from axlebox accelerations.

Role in the data flow (``shared/DESIGN.md``): the last link. Turns axlebox
accelerations of an in-service train (with position and speed) into rail
irregularity profiles through the transfer functions of :mod:`receptance`,
computes EN 13231-3 band indexes (thesis Table 4.1, eq. 4.1), averages runs
and follows corrugation growth over months.
"""
