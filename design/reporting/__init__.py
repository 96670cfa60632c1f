"""Reporting: the kit the problem pages are written with (numbers, tables, figures, claims) and the pages."""
