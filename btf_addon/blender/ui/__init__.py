"""Panels: the BTF material and render panels (``btf_panels.py``), the material's mapping
(``mapping.py``), the film (``film.py``) and Blender's own panels shown for this engine by
what it honours (``blender_panels.py``)."""
