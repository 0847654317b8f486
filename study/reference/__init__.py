"""Exact references: Embree hit points of the very rays the methods trace, Mitsuba path-traced images."""
