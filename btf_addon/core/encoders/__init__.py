"""Encoders: any BTF → a codec our decoders read (issue 16).

``mlvq.py`` writes the BTFbase MLVQ structure (``core/codecs/mlvq.py``); ``kmeans.py`` is the shared
vector quantiser; ``svd.py`` writes the ``svd`` codec (a truncated SVD per channel, streamed
through Gram matrices); ``metrics.py`` reports size, ratio, PSNR, SSIM and time.
"""
