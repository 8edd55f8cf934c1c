"""A tiny NumPy rasteriser for ``rgb_array`` frames (no pygame or matplotlib).

:class:`Canvas` holds an (H, W, 3) uint8 image and draws anti-alias-free primitives in
pixel coordinates (x to the right, y downwards) or, through :meth:`Canvas.to_pixels`, in
world coordinates.  Shared by the flexid environments.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Canvas"]

Color = tuple[int, int, int]


class Canvas:
    """An RGB frame to draw on.

    Parameters
    ----------
    width, height : int
        Frame size in pixels (>= 1).
    background : tuple of 3 int
        Background colour (0-255).
    """

    def __init__(self, width: int, height: int, background: Color = (255, 255, 255)):
        if int(width) < 1 or int(height) < 1:
            raise ValueError(f"canvas size must be >= 1 x 1 pixels, got {width} x {height}")
        self.width = int(width)
        self.height = int(height)
        self.image = np.empty((self.height, self.width, 3), dtype=np.uint8)
        self._yy, self._xx = np.mgrid[0 : self.height, 0 : self.width]
        self.fill(background)

    def fill(self, color: Color) -> Canvas:
        """Paint the whole frame with ``color``."""
        self.image[...] = np.asarray(color, dtype=np.uint8)
        return self

    def to_pixels(self, x, y, scale: float, origin: tuple[float, float]) -> tuple:
        """Map world coordinates (y up) to pixel coordinates (y down).

        ``origin`` is the pixel position of the world origin; ``scale`` is pixels per unit.
        """
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        return origin[0] + scale * x, origin[1] - scale * y

    def circle(self, cx: float, cy: float, radius: float, color: Color) -> Canvas:
        """Draw a filled disc of ``radius`` pixels centred at (cx, cy)."""
        r = max(float(radius), 0.5)
        x0, x1 = max(int(cx - r) - 1, 0), min(int(cx + r) + 2, self.width)
        y0, y1 = max(int(cy - r) - 1, 0), min(int(cy + r) + 2, self.height)
        if x0 >= x1 or y0 >= y1:
            return self
        xx = self._xx[y0:y1, x0:x1]
        yy = self._yy[y0:y1, x0:x1]
        mask = (xx - cx) ** 2 + (yy - cy) ** 2 <= r * r
        self.image[y0:y1, x0:x1][mask] = color
        return self

    def line(
        self, x0: float, y0: float, x1: float, y1: float, color: Color, thickness: float = 1.0
    ) -> Canvas:
        """Draw a segment from (x0, y0) to (x1, y1) with ``thickness`` pixels."""
        return self.polyline([x0, x1], [y0, y1], color, thickness)

    def polyline(self, xs, ys, color: Color, thickness: float = 1.0) -> Canvas:
        """Draw connected segments through the points ``(xs[i], ys[i])`` (pixel units)."""
        xs = np.asarray(xs, dtype=float)
        ys = np.asarray(ys, dtype=float)
        half = max(float(thickness), 1.0) / 2.0
        for i in range(len(xs) - 1):
            ax, ay, bx, by = xs[i], ys[i], xs[i + 1], ys[i + 1]
            lo_x = max(int(min(ax, bx) - half) - 1, 0)
            hi_x = min(int(max(ax, bx) + half) + 2, self.width)
            lo_y = max(int(min(ay, by) - half) - 1, 0)
            hi_y = min(int(max(ay, by) + half) + 2, self.height)
            if lo_x >= hi_x or lo_y >= hi_y:
                continue
            px = self._xx[lo_y:hi_y, lo_x:hi_x] - ax
            py = self._yy[lo_y:hi_y, lo_x:hi_x] - ay
            dx, dy = bx - ax, by - ay
            length2 = dx * dx + dy * dy
            t = np.zeros_like(px, dtype=float) if length2 == 0 else np.clip(
                (px * dx + py * dy) / length2, 0.0, 1.0
            )
            dist2 = (px - t * dx) ** 2 + (py - t * dy) ** 2
            self.image[lo_y:hi_y, lo_x:hi_x][dist2 <= half * half + 0.25] = color
        return self

    def rectangle(self, x0: float, y0: float, x1: float, y1: float, color: Color) -> Canvas:
        """Draw a filled axis-aligned rectangle between two corners (pixel units)."""
        a, b = sorted((round(x0), round(x1)))
        c, d = sorted((round(y0), round(y1)))
        a, b = max(a, 0), min(b + 1, self.width)
        c, d = max(c, 0), min(d + 1, self.height)
        if a < b and c < d:
            self.image[c:d, a:b] = color
        return self

    def frame(self) -> np.ndarray:
        """Return a copy of the frame, shape (height, width, 3), dtype uint8."""
        return self.image.copy()
