"""A sphere touched from outside, from the samples in contact (SPEC §21): its centre where the
lines of the normal forces meet, then its radius with the contact law, the sensor's latency and
low-pass, and friction, as for a plane (``contact.py``) on the coordinate −|X − c|."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from scipy import optimize

from admit_rs.identification.contact import MOVED, ContactFit, Law
from admit_rs.identification.least_squares import Array, alpha_of, ar1_inflation, low_pass_delay

MIN_TURN = 2.0
"""The least angle [°] the normal force must turn through in contact before a sphere's
centre is fitted (below it, the lines hardly meet: a plane is what the log shows)."""



class SphereFit(ContactFit):
    """Fits the contact samples of a log of a sphere touched from outside."""

    paths = ("wall.stiffness", "wall.damping", "wall.radius", "wall.centre", "sensor.latency",
             "sensor.cutoff")
    radius_slack: float = 0.0
    """The radius's interval widening [m] from the centre's and the bias's intervals (set by
    :meth:`run` before the radius is put)."""

    def run(self, free: npt.NDArray[np.bool_], static: Array) -> None:
        cell = self.cell
        world = cell.to_world(cell.reading - static)
        contact = ~free
        found = self.centre(world, contact)
        if found is None:
            return
        centre, cov = found
        window = self.fit_window(contact)
        # The lines fix the centre to millimetres; the law (k = 3e4 N/m turns 10 µm into
        # 0.3 N) to micrometres. Refine it by the law at a latency and cut-off, search those
        # again about the refined centre, twice (they trade off with the geometry only
        # weakly).
        latency, alpha = 0, 1.0
        free_directions = self.law_directions(centre, contact)
        search = None
        for _ in range(2):
            refined = self.refine(world, centre, cov, free_directions, contact, window,
                                  latency, alpha)  # fmt: skip
            if refined is None:
                break
            centre, cov = refined
            depth, rate, normals = self.coordinate(centre)
            s = np.sum(world * normals, axis=1)
            search = self.law_search(s, self.linear_law(depth, rate), contact, window)
            latency, alpha = search.latency, alpha_of(search.cutoff, cell.period)
        depth, rate, normals = self.coordinate(centre)
        s = np.sum(world * normals, axis=1)
        if search is None:  # the law's search about the final centre, if not done above
            search = self.law_search(s, self.linear_law(depth, rate), contact, window)
        k, kx = search.fit.coef[:2]
        if k <= 0:
            for path in (*self.paths, "wall.friction"):
                self.found.unidentified[path] = (
                    "the force read in contact does not grow as the tip nears the fitted "
                    "centre (no stiffness > 0 fits)"
                )
            return
        self.found.touching = search.touching
        q = self.found.t_quantile(search.fit.dof)
        half = np.sqrt(np.maximum(np.diag(cov), 0.0)) * q
        # Across the law's directions the lines place the centre, and the bias's interval
        # turns every force read alike: by |its part across| / f, at the lever |X − c|.
        across = np.eye(3) - free_directions.T @ free_directions
        bias_half = np.array([(b - a) / 2 for a, b in self.found.intervals["sensor.bias"]])
        rotation = cell.rotation[contact].mean(axis=0) if cell.tip_frame else np.eye(3)
        lever = float(np.median(np.linalg.norm(centre - cell.x[contact], axis=1)))
        force = float(np.median(np.linalg.norm(world[contact], axis=1)))
        for e in np.linalg.svd(across)[0][:, : 3 - len(free_directions)].T:
            turn = float(np.abs(rotation.T @ e) @ bias_half) / max(force, 1e-12)
            half = half + np.abs(e) * turn * lever
        self.found.put("wall.centre", tuple(float(v) for v in centre),
                       tuple((float(v - e), float(v + e)) for v, e in zip(centre, half,
                                                                          strict=True)),
                       "where the lines of the normal force read in contact (its part along "
                       "the velocity, friction, taken out) meet: least squares weighted by the "
                       "force squared, then moved along the mean normal and the path by the "
                       "contact law's residual (the interval from its Jacobian; across the "
                       "path from the lines' spread and the bias's interval)")  # fmt: skip
        # Along the mean normal the centre and the radius trade off one for one.
        touched = search.touching if search.touching.any() else contact
        mean_normal = normals[touched].mean(axis=0)
        mean_normal /= np.linalg.norm(mean_normal)
        self.radius_slack = float(math.sqrt(max(float(mean_normal @ cov @ mean_normal), 0.0))) * q
        self.radius_slack += float(np.abs(rotation.T @ mean_normal) @ bias_half) / k
        self.put_offset(float(kx / k), self.ratio_interval(search, 0.0, 1),
                        "the contact law's offset: the distance from the centre where the force "
                        "vanishes; the interval includes the centre's along the mean normal and "
                        "the bias's")  # fmt: skip
        self.put_law(search, s, window, "δ = R − |X − c|")
        self.hunt_crossley(s, (depth, rate), contact, window, search)
        latency, cutoff = self.found.values["sensor.latency"], self.found.values["sensor.cutoff"]
        alpha = alpha_of(cutoff, cell.period)
        # The normal turns as the tip slides over the sphere, and the force is read through
        # the low-pass and the latency: split it about the normal as read, N through the same
        # filter (at 0.3 rad/s and 5 ms of lag the current N put 0.6 % of f into friction).
        read = low_pass_delay(normals, alpha, latency)
        read /= np.linalg.norm(read, axis=1)[:, None]
        self.friction(static, read, contact, latency, alpha)

    def put_offset(self, offset: float, interval: tuple[float, float], how: str) -> None:
        """x_e = −R on the coordinate −|X − c|."""
        lo, hi = -interval[1] - self.radius_slack, -interval[0] + self.radius_slack
        self.found.put("wall.radius", -offset, (lo, hi), how)

    def coordinate(self, centre: Array) -> tuple[Array, Array, Array]:
        """The coordinate −|X − c| whose excess over x_e = −R is the penetration δ = R − |X − c|,
        its rate, and the unit normals towards the centre."""
        towards = centre - self.cell.x
        distance = np.linalg.norm(towards, axis=1)
        normals = towards / distance[:, None]
        return -distance, np.sum(self.cell.v * normals, axis=1), normals

    def law_directions(self, centre: Array, contact: npt.NDArray[np.bool_]) -> Array:
        """The directions (rows) along which the contact law places the centre: the mean
        normal and each tangent the tip's path spans by more than 1 mm. Off a path along one
        arc, the centre's distance from the arc's plane only trades with R in the normal
        force (R² − d² is what it fixes); there the lines of the force, whose sideways part
        is d/R of it, place the centre."""
        towards = centre - self.cell.x[contact]
        mean_normal = np.mean(towards / np.linalg.norm(towards, axis=1)[:, None], axis=0)
        mean_normal /= np.linalg.norm(mean_normal)
        path = self.cell.x[contact] - self.cell.x[contact].mean(axis=0)
        path = path - np.outer(path @ mean_normal, mean_normal)
        _, spread, directions = np.linalg.svd(path, full_matrices=False)
        spread = spread / math.sqrt(len(path))
        tangents = [directions[i] for i in range(2) if spread[i] > MOVED]
        return np.array([mean_normal, *tangents])

    def refine(self, world: Array, centre: Array, lines_cov: Array, directions: Array,
               contact: npt.NDArray[np.bool_], window: npt.NDArray[np.bool_], latency: int,
               alpha: float) -> tuple[Array, Array] | None:  # fmt: skip
        """The centre of least residual of the contact law (its coefficients fitted at each
        trial centre: variable projection) at ``latency`` and ``alpha``, moved along
        ``directions`` only, and its covariance: along them from the residual's Jacobian
        (AR(1) effective count), across them the lines' (``lines_cov``). ``None`` if the
        solver fails."""

        def residual(a: Array) -> Array:
            depth, rate, normals = self.coordinate(centre + a @ directions)
            s = np.sum(world * normals, axis=1)
            lsq, _ = self.law_fit(s, self.linear_law(depth, rate), contact, latency, alpha,
                                  window)  # fmt: skip
            return lsq.residuals

        start = np.zeros(len(directions))
        try:
            sol = optimize.least_squares(residual, start, x_scale=1e-3, diff_step=1e-7)
        except (ValueError, np.linalg.LinAlgError):
            return None
        if not np.all(np.isfinite(sol.x)):
            return None
        inflation, _ = ar1_inflation(sol.fun)
        s2 = float(sol.fun @ sol.fun) / max(len(sol.fun) - 3 - len(directions), 1)
        cov_law = np.linalg.pinv(sol.jac.T @ sol.jac) * s2 * inflation
        across = np.eye(3) - directions.T @ directions
        cov = directions.T @ cov_law @ directions + across @ lines_cov @ across
        return centre + np.asarray(sol.x, dtype=float) @ directions, cov

    @staticmethod
    def linear_law(depth: Array, rate: Array) -> Law:
        """f = k (depth − x_e) + c rate, linear in (k, k x_e, c) on the touching set."""

        def columns(ind: Array) -> Array:
            return np.column_stack([ind * depth, -ind, ind * rate])

        def force(coef: Array) -> Array:
            return coef[0] * depth - coef[1] + coef[2] * rate  # type: ignore[no-any-return]

        return Law(columns, force)

    def centre(self, world: Array,
               contact: npt.NDArray[np.bool_]) -> tuple[Array, Array] | None:  # fmt: skip
        """c minimising Σ w_i |P_i (c − X_i)|², P_i = I − u_i u_iᵀ the projection across the
        normal force's direction u_i at the tip position X_i (the force pushes towards the
        centre), w_i = |f_i|² (a direction's error is the noise over the force); and its
        covariance. ``None`` (every wall path unidentified, with why) where the directions
        turned too little for the lines to meet."""
        parts, index = self.normal_parts(world, contact)
        size = np.linalg.norm(parts, axis=1)
        keep = size > 0.2 * float(np.median(size)) if len(size) else size > 0
        if keep.sum() < 20:
            self.unidentified_sphere("fewer than 20 contact samples with a clear normal force")
            return None
        u = parts[keep] / size[keep, None]
        x = self.cell.x[index[keep]]
        w = size[keep] ** 2
        # How far the force turned with the path: the slope of its direction's part along
        # the path's main direction against the position along it (−1/R on a sphere, 0 on a
        # plane, whatever the noise), times the path's span.
        path = x - x.mean(axis=0)
        _, spread, directions = np.linalg.svd(path, full_matrices=False)
        along = path @ directions[0]
        span = float(np.percentile(along, 95) - np.percentile(along, 5))
        if spread[0] / math.sqrt(len(path)) <= MOVED:
            self.unidentified_sphere("the tip did not move along the surface in contact (by "
                                     "1 mm or more): a sphere's centre needs the force to "
                                     "turn")  # fmt: skip
            return None
        slope = float(np.polyfit(along, u @ directions[0], 1)[0])
        turn = math.degrees(abs(slope) * span)
        if turn < MIN_TURN:
            self.unidentified_sphere(
                f"the normal force turned by {turn:.2g}° over the {1e3 * span:.3g} mm the tip slid "
                f"(a sphere needs {MIN_TURN:g}° or more for its centre): the log shows a plane; "
                "fit surface='plane'"
            )
            return None
        projections = np.eye(3)[None, :, :] - u[:, :, None] * u[:, None, :]
        a = np.einsum("k,kij->ij", w, projections)
        b = np.einsum("k,kij,kj->i", w, projections, x)
        centre = np.linalg.solve(a, b)
        residual = np.einsum("kij,kj->ki", projections, centre - x)
        inflation, _ = ar1_inflation(residual.ravel(), columns=3)
        m = len(u)
        sigma2 = float(np.einsum("k,ki,ki->", w, residual, residual)) / max(2 * m - 3, 1)
        cov = sigma2 * inflation * np.linalg.inv(a)
        return centre, cov

    def unidentified_sphere(self, why: str) -> None:
        for path in (*self.paths, "wall.friction"):
            self.found.unidentified[path] = why
