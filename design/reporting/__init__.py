"""Reporting: the kit the problem pages are written with (:mod:`~fdisyn.reporting.kit`: numbers, tables, figures,
claims) and the pages (:mod:`~fdisyn.reporting.page`, with the standard figures of :mod:`~fdisyn.reporting.figures`,
the certificate tables of :mod:`~fdisyn.reporting.certificates` and the false-alarm budget of
:mod:`~fdisyn.reporting.budget`)."""
