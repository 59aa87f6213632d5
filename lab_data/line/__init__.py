"""lab_data.line — the virtual line: field runs of an instrumented metro bogie over rails whose roughness is known.

Role in the data flow (``shared/DESIGN.md``): it stands in for the train, its
odometry and a corrugation-measuring trolley. A time-domain simulation (the
virtual lab's as-built truth wheelsets on a discretely supported track with
non-linear Hertz contact) runs the bogie over a 1.8 km line
(:mod:`~lab_data.line.geometry`) whose rails carry broadband roughness,
corrugation growing over the days, welds, a switch and grinding
(:mod:`~lab_data.line.roughness`), at the speeds of an automatic train
operation (:mod:`~lab_data.line.operation`); sensors and DAQ
(:mod:`~lab_data.line.daq`) and odometry (:mod:`~lab_data.line.odometry`)
make the recorded channels; :mod:`~lab_data.line.files` writes MDF4 runs, the
sensor table, the line description, trolley CSVs and the truth. Field
scenarios hide effects the estimator's default model lacks
(:mod:`~lab_data.line.scenarios`). Like the lab, it never imports the toolkit
(``fem_import``, ``ema``, ``receptance``, ``estimator``).

Modules: the dynamics core (``track``, ``vehicle``, ``contact``, ``dynamics``,
``damping``) and the line around it (``geometry``, ``curving``, ``supports``,
``roughness``, ``operation``, ``odometry``, ``passage``, ``sensors``, ``daq``,
``files``, ``scenarios``, ``campaign``, ``cache``).

Entry points: :func:`lab_data.line.campaign.simulate_line`,
:func:`lab_data.line.cache.line_campaign_dir`,
:data:`lab_data.line.scenarios.FIELD_SCENARIOS`.
"""
