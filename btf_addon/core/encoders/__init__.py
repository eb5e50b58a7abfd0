"""Encoders: any BTF → a codec our decoders read (issue 16).

``mlvq.py`` writes the BTFbase MLVQ structure (``core/mlvq.py``); ``kmeans.py`` is the shared
vector quantiser; ``metrics.py`` reports size, ratio, PSNR and time. An SVD encoder waits for
the ``svd`` codec (issue 15).
"""
