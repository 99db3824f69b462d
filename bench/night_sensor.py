"""What a camera gives of a darker scene, and what an infrared imager gives of a lit one (``posed bench night``).

Three image models, each a plain function of an 8-bit BGR image (OpenCV's order), seeded where random:

* :func:`dim` — a colour CMOS camera in less light. The steps, per pixel and channel (the Bayer mosaic and its
  demosaicing are not modelled: each channel is treated as a pixel of its own):

  1. sRGB to linear (IEC 61966-2-1's transfer function);
  2. photo-electrons ``e = linear x full_well_e x f``: the original image is taken as correctly exposed at the
     *reference exposure* (its brightest pixel value is a full well) with the exposure time already at its
     longest (a frame-rate-limited rolling-shutter camera at 30 fps cannot expose longer than ~33 ms), so that
     every step of darkness below it is made up by gain alone; ``f`` is the light relative to that level;
  3. shot noise: ``Poisson(e)``; read noise: Gaussian, ``read_noise_e`` electrons rms, input-referred;
  4. auto-exposure: the gain ``G = target / metered`` that brings the mean signal back to its target (the
     original's mean, what the camera held at ``f = 1``), metered on the noisy image as a real AE meters it,
     clamped to ``[1, max_gain]``; once ``G`` reaches ``max_gain`` the image darkens with ``f``;
  5. the ADC: ``adc_bits`` bits over the full well (values below 0 and above full scale clip);
  6. back to sRGB, 8 bits (the ISP's gamma; no denoising, sharpening or white balance are modelled).

  Parameters (:class:`Sensor`, :data:`OV2740`): the RealSense D435's colour sensor is an OmniVision OV2740
  (1920x1080, 1.4 um pixel, 10-bit RAW, rolling shutter; FRAMOS's D435e manual, section 3.4, "Color Sensor",
  and the Linux ``ov2740`` driver, ``OV2740_RGB_DEPTH 10``). Its analog gain register runs 128..1983 in 1/128
  steps (Linux ``drivers/media/i2c/ov2740.c``: ``OV2740_ANAL_GAIN_MIN 128``, ``OV2740_ANAL_GAIN_MAX 1983``), i.e.
  at most 15.5x; the driver's "digital gain" registers are the white-balance gains (``OV2740_REG_MWB_*``), not
  used here for exposure, so ``max_gain = 1983 / 128``. OmniVision publishes no full well or read noise for the
  OV2740 that the search found; the values are **typical** of 1.4 um back-side-illuminated pixels of its
  generation (full wells of 4,000-6,000 e-, read noise 2-3 e- at high gain, as phone-sensor characterisations
  report): ``full_well_e = 4500``, ``read_noise_e = 2.5``. Dark current, fixed-pattern noise, lens shading and
  the ISP's noise reduction are not modelled (the last would make a real camera's dark image smoother).

* :func:`gray` — what an infrared imager gives of a lit scene: BT.601 luma (``0.299 R + 0.587 G + 0.114 B``)
  replicated to three channels. What it leaves out: skin and cloth reflect near infrared (850 nm) differently
  from visible light (skin is brighter, dyes often vanish), so the real contrast between a person and the room
  differs; the D435's infrared imagers (OmniVision OV9282, 1280x800, global shutter) also see a wider field
  (about 87 x 58 deg against the colour camera's 69 x 42).

* :func:`dot_pattern` and :func:`with_dots` — the projector's dots over a grayscale image. The D435 projects a
  static pseudo-random pattern of about 5,000 spots (Intel, "Projectors for Intel RealSense Depth Cameras
  D4xx", Grunnet-Jepsen et al., rev 1.0: the D435's AMS Princeton Optronics projector, "fewer spots (~5000)"
  than the D415's) at 850 nm (FRAMOS D435e manual, 3.3) over 86 x 57 deg, about its imagers' field: so
  :data:`DOTS` spots, uniformly random over the image (a real pattern is a tiled, quasi-random VCSEL layout),
  each a Gaussian spot of ``DOT_SIGMA_PX`` pixels at a 1280-pixel-wide image (scaled with the width: spots are
  a few pixels across on the D435's 1280x800 infrared image; typical, not measured), added on the image at a
  peak brightness of ``level`` times the frame's mean luma (clipped at 255). The pattern is fixed to the camera
  (one per clip, seeded); the parallax that moves the dots with depth, and the projector's fall-off with
  distance, are not modelled.

:func:`mean_luma` is the daemon's own (:func:`hal.night.mean_luma`: BT.601 luma averaged over every 8th row and
column), the darkness measure its night switch reads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posed.hal import mean_luma

BT601 = (0.114, 0.587, 0.299)      # weights of B, G, R (OpenCV's order), as hal.night's mean_luma uses them

DOTS = 5000                        # Intel's projector white paper: the D435 projects ~5,000 spots
DOT_SIGMA_PX = 1.0                 # a spot's Gaussian sigma at 1280 pixels of width (typical, not measured)
DOT_REF_WIDTH = 1280               # the D435's infrared image width (1280x800)


@dataclass(frozen=True)
class Sensor:
    """A camera sensor for :func:`dim` (see the module docstring for each value's source)."""

    name: str
    full_well_e: float       # electrons at full scale of the ADC at gain 1
    read_noise_e: float      # rms, input-referred
    max_gain: float          # the auto-exposure's largest gain
    adc_bits: int


OV2740 = Sensor("OV2740 (RealSense D435 colour), typical 1.4 um pixel", full_well_e=4500.0, read_noise_e=2.5,
                max_gain=1983 / 128, adc_bits=10)


def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1: sRGB values in [0, 1] to linear light in [0, 1]."""
    v = np.asarray(v, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(v: np.ndarray) -> np.ndarray:
    """The inverse of :func:`srgb_to_linear` (input clipped to [0, 1])."""
    v = np.clip(np.asarray(v, dtype=np.float64), 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)


def luma(image_bgr: np.ndarray) -> np.ndarray:
    """BT.601 luma of every pixel, float64 0-255."""
    return np.asarray(image_bgr, dtype=np.float64) @ np.asarray(BT601)


def gray(image_bgr: np.ndarray) -> np.ndarray:
    """The BT.601 luma rounded to 8 bits and replicated to three channels."""
    y = np.clip(np.rint(luma(image_bgr)), 0, 255).astype(np.uint8)
    return np.repeat(y[:, :, None], 3, axis=2)


POISSON_BELOW_E = 50.0     # exact Poisson draws below this mean; above it, Poisson's normal approximation


def shot_noise(mean_e: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Photo-electrons with Poisson statistics around ``mean_e`` (float64): exact draws where the mean is below
    :data:`POISSON_BELOW_E`, ``mean + sqrt(mean) x N(0, 1)`` above it (the same mean and variance; the skew
    left out is below 0.15 of a standard deviation there), which is faster on large means; float32."""
    mean_e = np.asarray(mean_e, dtype=np.float32)
    out = rng.standard_normal(mean_e.shape, dtype=np.float32)
    out *= np.sqrt(mean_e)
    out += mean_e
    low = mean_e < POISSON_BELOW_E
    out[low] = rng.poisson(mean_e[low])
    return out


@dataclass(frozen=True)
class Dimmed:
    image: np.ndarray     # uint8, the shape of the input
    gain: float           # the auto-exposure's gain
    clamped: bool         # the gain reached max_gain (the image darkens past this)


def dim(image_bgr: np.ndarray, f: float, rng: np.random.Generator, sensor: Sensor = OV2740) -> Dimmed:
    """``image_bgr`` as ``sensor`` would give it with the light times ``f`` (module docstring, steps 1-6)."""
    if not 0.0 < f <= 1.0:
        raise ValueError(f"the light fraction must be in (0, 1], got {f}")
    image = np.asarray(image_bgr)
    if image.dtype != np.uint8:
        raise ValueError(f"expected an 8-bit image, got {image.dtype}")
    lin = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)[image]   # a table: the same values, faster
    target = float(lin.mean(dtype=np.float64)) * sensor.full_well_e          # the AE's target: the original's mean signal
    electrons = shot_noise(lin * (sensor.full_well_e * f), rng)
    electrons += np.float32(sensor.read_noise_e) * rng.standard_normal(electrons.shape, dtype=np.float32)
    metered = float(electrons.mean(dtype=np.float64))
    gain = sensor.max_gain if metered <= 0 else float(np.clip(target / metered, 1.0, sensor.max_gain))
    full = 2 ** sensor.adc_bits - 1
    dn = np.clip(np.rint(electrons * np.float32(gain / sensor.full_well_e * full)), 0, full)
    to_8bit = np.rint(linear_to_srgb(np.arange(full + 1) / full) * 255.0).astype(np.uint8)
    out = to_8bit[dn.astype(np.int64)]
    return Dimmed(out, gain, gain >= sensor.max_gain)


def dot_pattern(height: int, width: int, seed: int, dots: int = DOTS, sigma_px: float | None = None) -> np.ndarray:
    """(height, width) float32: ``dots`` Gaussian spots at seeded uniform random places, each peaking at 1
    (overlapping spots add). ``sigma_px`` default: :data:`DOT_SIGMA_PX` scaled by width / 1280."""
    import cv2

    sigma = DOT_SIGMA_PX * width / DOT_REF_WIDTH if sigma_px is None else float(sigma_px)
    rng = np.random.default_rng(seed)
    ys = rng.integers(0, height, size=dots)
    xs = rng.integers(0, width, size=dots)
    impulses = np.zeros((height, width), np.float32)
    np.add.at(impulses, (ys, xs), 1.0)
    k = int(np.ceil(4 * sigma)) * 2 + 1
    blurred = cv2.GaussianBlur(impulses, (k, k), sigma, borderType=cv2.BORDER_CONSTANT)
    # a lone spot's peak after the blur is the centre weight of the separable kernel, squared
    centre = float(cv2.getGaussianKernel(k, sigma)[k // 2, 0]) ** 2
    return blurred / np.float32(centre)


def with_dots(image_bgr: np.ndarray, pattern: np.ndarray, level: float) -> np.ndarray:
    """The image with ``pattern`` added at a peak of ``level`` x the image's mean luma, clipped to 255."""
    amplitude = level * mean_luma(image_bgr)
    out = np.asarray(image_bgr, dtype=np.float32) + (amplitude * pattern)[:, :, None]
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
