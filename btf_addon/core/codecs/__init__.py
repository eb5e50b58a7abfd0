"""Codecs: each a ``core.model.BTF`` that decodes one representation (MLVQ, dense, analytic,
microgeometry, SVD), registered with its device id and pack function in ``packed.py`` (the
packed GPU table layout); MLVQ's packing beside it (``mlvq_pack.py``), its BTFbase text
tables too (``btfbase_files.py``: the codec's own serialisation). Imports sampling/ and the
modules directly under core/."""
