"""What accuracy costs in time, inside Blender: the Estimate Quality vs Time operator, its panel
and Apply Recommended (``operator.py``), and the scene exported once and each rung rendered as
F12 renders it (``run.py``) over the bpy-free ladder (render/accuracy/)."""
