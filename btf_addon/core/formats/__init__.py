"""Formats: files → BTFs and back. The one loader (``load.py`` ``load_btf``), the ``.btfm``
container, BTFbase ``binary.btf``, UBO2014 DFMF, UBO2003/ATRIUM image sets, Radiance HDR and
EXR/PNG images (``imageio.py``). Imports codecs/, sampling/ and the modules directly under
core/ (docs/formats.md)."""
