"""lab_data — the virtual wheelset lab: a known truth and the files a real campaign writes.

Role in the data flow (``shared/DESIGN.md``): it stands in for the laboratory
(and, later, the train). From a 3D finite-element wheelset like thesis
Table 2.1 it writes the design FE export (UFF 2411/2412/55 and Nastran
punch), the impact-test time histories of the two setups (binary UFF58 + channel
tables), the points table and a truth manifest, for named scenarios whose
as-built truth hides physical effects the design model lacks. It never
imports the toolkit (``fem_import``, ``ema``, ``receptance``,
``estimator``): test data is never made by the code that inverts it.

Entry points: :func:`lab_data.campaign.simulate`,
:func:`lab_data.cache.campaign_dir`, :data:`lab_data.scenarios.SCENARIOS`.
"""
