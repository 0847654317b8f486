"""Caustics (the paper's Figure 8): caustic maps from the light through the glass object, photon hits localized
by a method in the impostor (``photons``), light maps and splatting (``lightmap``), and the caustic study against
exact photon tracing and Mitsuba (``study``, ``figure``)."""
