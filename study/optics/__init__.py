"""Light at the shaded object: Snell's law, dielectric Fresnel and paths through glass (``interfaces``); camera
ray → object hit → secondary rays (reflected, refracted) → Fresnel weights → composited image (``shading``); the
object's own distance map searched for its far side (``distance_map``, on the methods' search core)."""
