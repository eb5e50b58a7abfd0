"""bpy-free render logic over plain arrays: final-render driver, progressive viewport state,
stereo camera maths."""
