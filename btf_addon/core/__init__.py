"""Numpy-only core: BTF data model, codecs, colour transforms, environment sampling.

Never imports bpy, pyopencl or moderngl (a test checks this in a subprocess).
"""
