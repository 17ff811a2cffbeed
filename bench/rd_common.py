"""What the rate-distortion benches share: the PSNR every method is judged by and the plot."""
import numpy as np


def psnr(ref, test):
    """PSNR in dB with the reference's value range as peak, as voxwall::codec::psnr."""
    ref = ref.astype(np.float64)
    mse = np.mean((ref - test.astype(np.float64)) ** 2)
    peak = float(ref.max() - ref.min()) or 255.0
    return float("inf") if mse == 0 else 10 * np.log10(peak * peak / mse)


def plot(path, title, rows, points=()):
    """PSNR against bits per voxel, one line per row["method"] (markers only for the methods in
    `points`, whose rows are separate settings rather than a curve); lossless rows are left out."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for method in dict.fromkeys(r["method"] for r in rows):
        pts = sorted((r["bpv"], r["psnr"]) for r in rows
                     if r["method"] == method and r["psnr"] != float("inf"))
        if pts:
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "o" if method in points else "o-",
                    label=method)
    ax.set_xscale("log", base=2)
    ax.set_xlabel("bits per voxel")
    ax.set_ylabel("PSNR (dB)")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
