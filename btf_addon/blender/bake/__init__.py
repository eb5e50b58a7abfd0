"""Bake Light for VR: the scene's light transport precomputed per object (cl/bake.py), from the
command line (`python -m btf_addon bake`) and, next, from the operator, through one function."""
