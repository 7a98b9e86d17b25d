"""Training augmentation: photometric jitter (brightness, contrast, saturation, colour gains, offsets) and
small shifts and scalings, so a trained encoder does not key on lighting or exact framing."""

from __future__ import annotations

from typing import Any, Final

from robofailring.extras import needs_extra

AUGMENTATION: Final[dict[str, float]] = {
    "brightness": 0.4,  # × U(1 − b, 1 + b)
    "contrast": 0.4,  # around the image mean, × U(1 − c, 1 + c)
    "saturation": 0.5,  # colour around grey, × U(1 − s, 1 + s)
    "colour_gain": 0.25,  # per channel × U(1 − g, 1 + g)
    "offset": 0.08,  # per channel + U(−o, o)
    "shift": 0.08,  # translation, fraction of the image side
    "scale": 0.12,  # zoom × U(1 − s, 1 + s)
}


def augment(pixels: Any, generator: Any) -> Any:
    """Photometric and small geometric augmentation of a (B, 3, S, S) batch in [0, 1], seeded."""
    with needs_extra("clip"):
        import torch
        import torch.nn.functional as F

    count = pixels.shape[0]

    def uniform(spread: float, *shape: int) -> torch.Tensor:
        return (torch.rand(count, *shape, generator=generator) * 2 - 1) * spread

    a = AUGMENTATION
    grey = pixels.mean(dim=1, keepdim=True)
    pixels = (pixels - grey) * (1 + uniform(a["saturation"], 1, 1, 1)).to(pixels) + grey
    mean = pixels.mean(dim=(1, 2, 3), keepdim=True)
    pixels = (pixels - mean) * (1 + uniform(a["contrast"], 1, 1, 1)).to(pixels) + mean
    pixels = pixels * (1 + uniform(a["brightness"], 1, 1, 1)).to(pixels)
    pixels = pixels * (1 + uniform(a["colour_gain"], 3, 1, 1)).to(pixels) + uniform(a["offset"], 3, 1, 1).to(
        pixels
    )
    scale = 1 + uniform(a["scale"])
    theta = torch.zeros(count, 2, 3)
    theta[:, 0, 0] = theta[:, 1, 1] = 1 / scale
    theta[:, :, 2] = uniform(2 * a["shift"], 2)  # affine_grid coordinates span 2 per side
    grid = F.affine_grid(theta.to(pixels), list(pixels.shape), align_corners=False)
    return F.grid_sample(pixels, grid, padding_mode="border", align_corners=False).clamp_(0, 1)
