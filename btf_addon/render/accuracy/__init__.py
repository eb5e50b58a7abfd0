"""What accuracy costs in time: the accuracy report's own room (bpy- and device-free).

``ladder.py``: the quality knobs as data, the ladder of rungs swept from a scene's settings,
the error measures (relative RMSE, 1 − SSIM), the time model and the run loop over an injected
render callable. ``plot.py``: the numpy line-plot and heat-map raster. ``report.py``: the
report's JSON, Markdown, HTML and PNGs. Blender's operator (blender/accuracy/operator.py,
blender/accuracy/run.py) and the CLI (cli/accuracy_command.py) drive it.
"""
