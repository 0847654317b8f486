"""Caustics (the paper's Figure 8): caustic maps from the light through the glass object, photon hits localized
by a method in the impostor (``photons``), light maps and splatting (``lightmap``), the caustic study against
exact photon tracing and Mitsuba (``study``, ``figure``) and Figure 8's image as one would publish it: baked
indirect light, density-adaptive caustic splats (``display``)."""
