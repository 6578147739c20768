"""The fit's order (free space, contact, noise) and the free-space fits: the sensor's bias,
the tool's weight, the noise level."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import polars as pl
from scipy import stats

from admit_rs.identification.cell_fit import CellFit
from admit_rs.identification.contact import ContactFit
from admit_rs.identification.findings import Findings
from admit_rs.identification.least_squares import (
    Array,
    alpha_of,
    ar1_inflation,
    least_squares,
)
from admit_rs.identification.log_arrays import LogArrays
from admit_rs.identification.sphere import SphereFit
from admit_rs.recording import LogError

UNSEEN_CONTACT = 1.0
"""A contact force [N] the noise may hide before a log without contact is doubted."""


class Fitter:
    """Fits a log's cell: free space first (the bias, the weight), then contact, then the
    noise (whose scaling needs the low-pass found in contact)."""

    def __init__(self, cell: LogArrays, confidence: float, stiction: float,
                 surface: str = "plane") -> None:  # fmt: skip
        self.cell = cell
        self.stiction = stiction
        self.surface = surface
        self.found = Findings(confidence)
        self.found.touching = np.zeros(len(cell.t), dtype=bool)

    def fit(self) -> CellFit:
        free, static = self.free_space()
        contact = ~free
        self.found.touching = contact
        fit = (SphereFit if self.surface == "sphere" else ContactFit)(self.cell, self.found,
                                                                      self.stiction)  # fmt: skip
        if contact.sum() < 50:
            for path in fit.paths:
                self.found.unidentified[path] = "no contact in the log (fewer than 50 samples)"
            self.found.unidentified["wall.friction"] = "no contact in the log"
        else:
            fit.run(free, static)
        self.noise(free)
        # Phases: touching where the fitted law's force is positive (else where the reading
        # leaves the free-space model), an impact for 50 ms after each first touch.
        touching = self.found.touching
        phases = np.where(touching, "contact", "free").astype(object)
        onsets = np.nonzero(touching[1:] & ~touching[:-1])[0] + 1
        if touching[0]:
            onsets = np.concatenate([[0], onsets])
        impact = max(1, int(round(0.05 / self.cell.period)))
        for k in onsets:
            phases[k : k + impact] = np.where(touching[k : k + impact], "impact",
                                              phases[k : k + impact])  # fmt: skip
        self.found.unidentified["tool.com"] = (
            "needs the torques and the six-axis tool of SPEC §19 (issue 'Six axes'), not built"
        )
        segments = pl.DataFrame({"t": self.cell.t, "phase": phases.astype(str)})
        f = self.found
        return CellFit(f.values, f.intervals, f.unidentified, f.how, segments, f.confidence,
                       self.stiction, f.residual_std, tuple(self.doubts(free, static)))  # fmt: skip

    def doubts(self, free: npt.NDArray[np.bool_], static: Array) -> list[str]:
        """Why the fit should not be trusted, if it should not: a step in what was taken for
        free space (contact hidden in the noise), a contact force within the noise, a
        stiffness known to no better than ±50 %."""
        out = []
        v = self.found.values
        resid = (self.cell.reading - static)[free]
        # The largest step in the mean of the free-space reading, in standard errors
        # (CUSUM, each axis, AR(1) effective counts): free space has none.
        _, rho = ar1_inflation(resid.ravel(), columns=3)
        scale = math.sqrt((1 + rho) / (1 - rho))
        for axis in range(3):
            r = resid[:, axis] - resid[:, axis].mean()
            sigma = float(np.std(r))
            n = len(r)
            if sigma <= 0 or n < 20:
                continue
            k = np.arange(1, n)
            cusum = np.cumsum(r)[:-1]
            # The step between the samples before k and after: mean difference / its error.
            step = np.abs(cusum) * n / (k * (n - k))
            z = step / (sigma * scale * np.sqrt(1 / k + 1 / (n - k)))
            worst = int(np.argmax(z))
            if z[worst] > 6:
                t = float(self.cell.t[np.nonzero(free)[0][worst]])
                out.append(f"the reading taken for free space steps by {step[worst]:.3g} N on "
                           f"axis {'xyz'[axis]} at t = {t:.3g} s ({z[worst]:.0f} standard "
                           "errors): a contact hidden in the noise? The fit is not "
                           "trustworthy")  # fmt: skip
                break
        alpha = alpha_of(v.get("sensor.cutoff"), self.cell.period)
        noise_read = v.get("sensor.noise_std", 0.0) * math.sqrt(alpha / (2 - alpha))
        if "wall.stiffness" not in v and not out:
            # No contact found: the smallest contact force (held over half the log) the
            # step test would have seen. Above 1 N, a pressing could hide in the noise.
            unseen = 6 * noise_read * scale * 2 / math.sqrt(max(int(free.sum()), 1))
            if unseen > UNSEEN_CONTACT:
                out.append(f"no contact found, but the noise ({noise_read:.3g} N as read) would "
                           f"hide a contact force of up to {unseen:.3g} N held over half the log, "
                           "which the bias would absorb: the fit is not trustworthy")  # fmt: skip
        level = self.found.contact_level
        if level is not None and level < 3 * noise_read:
            out.append(f"the force in contact ({level:.3g} N, median) is within 3× the noise as "
                       f"read ({noise_read:.3g} N): the fit is not trustworthy")  # fmt: skip
        if "wall.stiffness" in self.found.intervals:
            lo, hi = self.found.intervals["wall.stiffness"]
            k = v["wall.stiffness"]
            if k <= 0 or (hi - lo) / 2 > 0.5 * k:
                out.append(f"the stiffness is known only to [{lo:.3g}, {hi:.3g}] N/m: not "
                           "trustworthy for predictions that depend on it")  # fmt: skip
        return out

    # 1. Free space -------------------------------------------------------------------------

    def free_space(self) -> tuple[npt.NDArray[np.bool_], Array]:
        """The free-space mask and the static reading β + R_kᵀ w per sample."""
        y = self.cell.reading
        n = len(y)
        # The start's reading, from its first 50 ms at most (a fiftieth of a 60-s log is 1.2 s,
        # longer than an approach: the median was the contact's, and the bias absorbed it).
        head = max(20, min(n // 50, int(round(0.05 / self.cell.period))))
        start = np.median(y[:head], axis=0)
        spread = np.median(np.abs(y[:head] - start), axis=0) * 1.4826
        sigma = max(float(np.max(spread)), 1e-6)
        deviation = np.linalg.norm(y - start, axis=1)
        scale = float(np.max(deviation))
        free = deviation < max(8 * sigma, 0.02 * scale)
        up = self.cell.up_in_sensor()
        fit_mass = False
        coef = np.concatenate([start, [0.0]])
        for _ in range(4):
            if free.sum() < 20:
                raise LogError(
                    "the log has no free space to fit the sensor from: identify() needs the "
                    "recording to start with the tool off the part (at least 20 samples)"
                )
            # Orientation spread of the weight's direction in free space: the mass needs it.
            centred = up[free] - up[free].mean(axis=0)
            spread_up = float(np.linalg.svd(centred, compute_uv=False)[0]) / math.sqrt(free.sum())
            fit_mass = spread_up > 0.05 * self.cell.gravity
            design = self.static_design(free, up, fit_mass)
            lsq = least_squares(design, y[free].reshape(-1), columns=3)
            coef = lsq.coef if fit_mass else np.concatenate([lsq.coef, [0.0]])
            static = coef[:3] + coef[3] * up
            resid = np.linalg.norm(y - static, axis=1)
            sigma = max(float(np.std((y - static)[free])), 1e-6)
            scale = float(np.max(resid))
            new = resid < max(8 * sigma, 0.02 * scale)
            # Keep clear of contact: a guard band around every contact sample.
            guard = max(1, int(round(0.05 / self.cell.period)))
            near = np.convolve((~new).astype(float), np.ones(2 * guard + 1), "same") > 0
            new = new & ~near
            if np.array_equal(new, free):
                break
            free = new
        q = self.found.t_quantile(lsq.dof)
        err = np.sqrt(np.maximum(np.diag(lsq.cov), 0.0)) * q
        bias = tuple(float(b) for b in coef[:3])
        bias_iv = tuple((float(b - e), float(b + e))
                        for b, e in zip(coef[:3], err[:3], strict=True))  # fmt: skip
        frame = "tip" if self.cell.tip_frame else "base"
        if fit_mass:
            self.found.put("sensor.bias", bias, bias_iv,
                     f"free space ({int(free.sum())} samples, the tool at several "
                     "orientations): least squares on y = β + Rᵀ(0, 0, g) m, "
                     f"{frame} frame")  # fmt: skip
            self.found.put("sensor.tool_mass", float(coef[3]),
                     (float(coef[3] - err[3]), float(coef[3] + err[3])),
                     "free space: the weight's change with the tool's orientation")  # fmt: skip
        else:
            self.found.put("sensor.bias", bias, bias_iv,
                     f"free space ({int(free.sum())} samples): the mean reading, {frame} "
                     "frame. The tool kept one orientation, so this is the bias plus the "
                     "tool's weight in that pose (a scenario with tool_mass 0 reads the "
                     "same)")  # fmt: skip
            self.found.unidentified["sensor.tool_mass"] = (
                "the tool kept one orientation in free space: its weight cannot be told from "
                "the bias (record the tool turned through a few poses)"
            )
        return free, static

    @staticmethod
    def static_design(free: npt.NDArray[np.bool_], up: Array, fit_mass: bool) -> Array:
        m = int(free.sum())
        eye = np.tile(np.eye(3), (m, 1))
        if not fit_mass:
            return eye
        return np.hstack([eye, up[free].reshape(-1, 1)])

    def noise(self, free: npt.NDArray[np.bool_]) -> None:
        static = np.asarray(self.found.values["sensor.bias"]) + self.found.values.get(
            "sensor.tool_mass", 0.0) * self.cell.up_in_sensor()[free]
        resid = (self.cell.reading[free] - static).ravel()
        sigma_y = float(np.std(resid))
        # A sample variance of an AR(1) series counts n (1 − ρ²)/(1 + ρ²) samples.
        _, rho = ar1_inflation(resid, columns=3)
        n_eff = max(resid.size * (1 - rho**2) / (1 + rho**2), 2.0)
        lo_q = stats.chi2.ppf(0.5 + self.found.confidence / 2, n_eff)
        hi_q = stats.chi2.ppf(0.5 - self.found.confidence / 2, n_eff)
        cutoff = self.found.values.get("sensor.cutoff")
        period = self.cell.period

        def gain(fc: float | None) -> float:
            # A first-order low-pass passes α/(2 − α) of white noise's variance.
            alpha = alpha_of(fc, period)
            return math.sqrt((2 - alpha) / alpha)

        sigma_u = sigma_y * gain(cutoff)
        # Over the cut-off's interval as well: a lower cut-off hides more noise.
        cut_iv = self.found.intervals.get("sensor.cutoff")
        gains = [gain(cutoff)] if cut_iv is None else [gain(cut_iv[0]), gain(cut_iv[1])]
        lo = sigma_y * math.sqrt(n_eff / lo_q) * min(gains)
        hi = sigma_y * math.sqrt(n_eff / hi_q) * max(gains)
        filt = (" (no cut-off identified: the noise as read)" if cutoff is None else
                f", scaled by √((2 − α)/α) = {gain(cutoff):.3g} for the low-pass")  # fmt: skip
        self.found.put("sensor.noise_std", sigma_u, (lo, hi),
                 f"free space: the residual's standard deviation {sigma_y:.3g} "
                 f"N{filt}")  # fmt: skip

    # 2. Contact ----------------------------------------------------------------------------
