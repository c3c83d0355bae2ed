"""Write src/prefilter/scenes/data/jacksboro-dem.png: real elevation data for the tabulated-driver presets.

Source: the Jacksboro fault digital elevation model that matplotlib ships as sample data
(`matplotlib.cbook.get_sample_data("jacksboro_fault_dem.npz")`, USGS, 3 arc-second grid). A 256 x 256
crop is mirrored into a seamless 512 x 512 tile and stored as a 16-bit PNG of (elevation - min) / range.
"""

from pathlib import Path

import imageio.v3 as iio
import matplotlib.cbook as cbook
import numpy as np

out = Path(__file__).resolve().parent.parent / "src/prefilter/scenes/data/jacksboro-dem.png"
elevation = np.asarray(cbook.get_sample_data("jacksboro_fault_dem.npz")["elevation"], dtype=np.float64)
crop = elevation[40:296, 60:316]
tile = np.block([[crop, crop[:, ::-1]], [crop[::-1, :], crop[::-1, ::-1]]])
normalised = (tile - tile.min()) / (tile.max() - tile.min())
iio.imwrite(out, np.round(normalised * 65535).astype(np.uint16))
print(f"{out}: {tile.shape[1]}x{tile.shape[0]}, elevation {tile.min():.0f}..{tile.max():.0f} m")
