"""An independent scalar BTFbase decoder for tests: plain Python loops over one query at a time,
written from the format facts in DESIGN.md (not from btf_addon.core.codecs.mlvq), reading the text
tables with numpy.loadtxt."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np


class ScalarMLVQ:
    def __init__(self, directory: Path):
        d = Path(directory)
        lines = [ln.split() for ln in (d / "all_materialInfo.txt").read_text().splitlines()]
        par = [int(x) for x in lines[10]]
        self.cos_beta, self.nb, self.na, self.nt, self.nf = par[0], par[1], par[3], par[5], par[7]
        mat = lines[14]
        self.name = mat[0]
        self.ro, self.co = int(mat[4]), int(mat[5])
        hdr = float(mat[8])
        self.hdr = not (abs(hdr - 1) < 1e-6 or abs(hdr) < 1e-6)
        self.hdr_value = hdr if self.hdr else 1.0

        def table(name):
            return np.loadtxt(d / name, skiprows=1, ndmin=2)

        self.p1 = table("all_PDF1Dslice.txt")
        self.ab = table("all_colors.txt")
        self.iab = table("all_indexAB.txt").astype(int)
        self.p2c = table("all_PDF2Dcolours.txt").astype(int)
        self.p2s = table("all_PDF2Dslices.txt").astype(int)
        self.p2sc = table("all_PDF2Dscale.txt")
        self.p2i = table("all_PDF2Dindices.txt").astype(int)
        self.p3 = table("all_PDF3Dslices.txt").astype(int)
        self.p3sc = table("all_PDF3Dscale.txt")
        self.p4 = table("all_PDF4Dslices.txt").astype(int)
        self.p4sc = table("all_PDF4Dscale.txt")
        self.p6 = table(f"{self.name}_PDF6Dslices.txt").astype(int)
        self.p6sc = table(f"{self.name}_PDF6Dscale.txt")
        n = self.nb
        if self.cos_beta:
            self.beta_deg = [
                math.degrees(math.asin(max(-1.0, min(1.0, -1 + 2 * i / (n - 1))))) for i in range(n)
            ]
        else:
            self.beta_deg = [i * 180 / (n - 1) - 90 for i in range(n)]
        self.beta_deg[0], self.beta_deg[(n - 1) // 2], self.beta_deg[-1] = -90.0, 0.0, 90.0

    def hermite(self, s, i, w):
        row = self.p1[s]
        p0, p1 = row[i], row[i + 1]
        m0 = p1 - p0 if i == 0 else 0.5 * (p1 - row[i - 1])
        m1 = p1 - p0 if i == self.nb - 2 else 0.5 * (p1 - p0)
        return (
            (2 * w**3 - 3 * w**2 + 1) * p0
            + (w**3 - 2 * w**2 + w) * m0
            + (-2 * w**3 + 3 * w**2) * p1
            + (w**3 - w**2) * m1
        )

    def pdf2(self, idx, ia, wa, ib, wb):
        lum_fn, col_fn = self.p2i[idx]
        y = cb = cr = 0.0
        for a, w in ((ia, 1 - wa), (ia + 1, wa)):
            y += w * self.p2sc[lum_fn, a] * self.hermite(self.p2s[lum_fn, a], ib, wb)
            c = self.p2c[col_fn, a]
            ab = (1 - wb) * self.ab[self.iab[c, ib]] + wb * self.ab[self.iab[c, ib + 1]]
            cb += w * ab[0]
            cr += w * ab[1]
        if self.hdr:
            return logluv(y, cb, cr)
        rgb = [
            1.1643828 * y + 1.5960273 * cr - 222.921,
            1.1643828 * y - 0.39176172 * cb - 0.81296875 * cr + 135.576,
            1.1643828 * y + 2.0172344 * cb - 276.836,
        ]
        return np.array([max(0.0, c) for c in rgb])

    def decode(self, u, v, ti, pi, tv, pv) -> np.ndarray:
        if ti > 90 or tv > 90:
            return np.zeros(3)
        rows, cols = self.p6.shape
        x = (math.floor(u * cols) - self.co) % cols
        y = (math.floor(v * rows) - self.ro) % rows
        vphi = (360 - pv) % 360
        iphi = ((360 - pi) - (90 + vphi)) % 360
        xx = math.cos(math.radians(iphi)) * math.sin(math.radians(ti))
        yy = math.sin(math.radians(iphi)) * math.sin(math.radians(ti))
        beta = math.asin(xx)
        alpha = 0.0 if math.cos(beta) < 1e-3 else math.asin(max(-1, min(1, yy / math.cos(beta))))
        beta, alpha = math.degrees(beta), math.degrees(alpha)
        # beta: index from sin β, weight in angle
        ib = min(max(int((math.sin(math.radians(beta)) + 1) / 2 * (self.nb - 1)), 0), self.nb - 2)
        wb = (beta - self.beta_deg[ib]) / (self.beta_deg[ib + 1] - self.beta_deg[ib])
        step_a = 180 / (self.na - 1)
        ia = min(max(int((alpha + 90) / step_a), 0), self.na - 2)
        wa = (alpha + 90 - ia * step_a) / step_a
        step_t = 90 / (self.nt - 1)
        it = min(max(int(tv / step_t), 0), self.nt - 2)
        wt = (tv - it * step_t) / step_t
        step_f = 360 / self.nf
        ip = min(max(int(vphi / step_f), 0), self.nf - 1)
        wp = (vphi - ip * step_f) / step_f
        p4 = self.p6[y, x] - 1
        out = np.zeros(3)
        for k, wk in ((ip, 1 - wp), ((ip + 1) % self.nf, wp)):
            p3 = self.p4[p4, k]
            for j, wj in ((it, 1 - wt), (it + 1, wt)):
                p2 = self.p3[p3, j]
                out += wk * self.p4sc[p4, k] * wj * self.p3sc[p3, j] * self.pdf2(p2, ia, wa, ib, wb)
        return out * self.p6sc[y, x] / self.hdr_value


def logluv(l_code: float, u: float, v: float) -> np.ndarray:
    """Mantiuk 2006 luminance (three pieces), u'v' chromaticity scaled by 410, sRGB matrix,
    clamp, sRGB curve — one value at a time."""
    if l_code < 98.381:
        y = 0.056968 * l_code
    elif l_code < 1204.7:
        y = 7.3014e-30 * (l_code + 884.17) ** 9.9872
    else:
        y = 32.994 * math.exp(0.0047811 * l_code)
    if v > 0:
        x = 9.0 / 4.0 * u / v * y
        z = y * (3.0 * 410.0 / v - 5.0) - x / 3.0
    else:
        x = z = 0.0
    rgb = [
        3.2406 * x - 1.5372 * y - 0.4986 * z,
        -0.9689 * x + 1.8758 * y + 0.0415 * z,
        0.0557 * x - 0.2040 * y + 1.0570 * z,
    ]
    out = []
    for c in rgb:
        c = max(c, 0.0)
        out.append(1.055 * c ** (1 / 2.4) - 0.055 if c > 0.0031308 else 12.92 * c)
    return np.array(out)
