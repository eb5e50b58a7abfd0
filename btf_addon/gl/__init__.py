"""OpenGL back end: GLSL assembly from shaders/*.glsl for Blender's gpu module and moderngl.

moderngl is imported inside functions, so this package imports without it.
"""
