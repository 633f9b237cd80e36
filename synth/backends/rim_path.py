"""Mitsuba's path tracer for synth's scene: no caustics of the ball on trough or backdrop.

Imported by :mod:`synth.backends.pathtrace` after it has chosen Mitsuba's variant (``@dr.syntax``
rewrites :meth:`RimPath.sample` with this module's globals, so ``mi`` and ``dr`` live here).
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi
from mitsuba.ad.integrators.common import RBIntegrator, mis_weight


class RimPath(RBIntegrator):
    """A path tracer (next-event estimation with multiple importance sampling, Mitsuba's
    ``prb`` primal pass) in which a glossy surface (the ball: trough and backdrop are
    diffuse) is black when a path reaches it from a diffuse surface.

    That leaves out one kind of light only: lamp light reflected by the ball onto the trough
    and backdrop (caustics), which a path tracer finds only by chance from a small lamp and
    shows as rare very bright pixels. The ball's own image (its reflections of lamps,
    backdrop and trough) and every shadow are path traced as usual.
    """

    @dr.syntax
    def sample(self, mode, scene, sampler, ray, δL, state_in, active, **kwargs):  # noqa: ARG002
        """Radiance along ``ray`` (primal only; see ``ADIntegrator.sample``)."""
        bsdf_ctx = mi.BSDFContext()
        ray = mi.Ray3f(ray)
        depth = mi.UInt32(0)
        L = mi.Spectrum(0)
        beta = mi.Spectrum(1)
        active = mi.Bool(active)
        diffuse_seen = mi.Bool(False)
        si_prev = dr.zeros(mi.SurfaceInteraction3f)
        pdf_prev = mi.Float(1.0)
        delta_prev = mi.Bool(True)
        while dr.hint(active, max_iterations=self.max_depth, label="synth_rim_path"):
            active_next = mi.Bool(active)
            si = scene.ray_intersect(ray, ray_flags=mi.RayFlags.All, coherent=depth == 0)
            bsdf = si.bsdf(ray)
            glossy = mi.has_flag(bsdf.flags(), mi.BSDFFlags.Glossy)
            blocked = diffuse_seen & glossy & si.is_valid()
            # light of an emitter hit by BSDF sampling, weighed against next-event estimation
            ds = mi.DirectionSample3f(scene, si=si, ref=si_prev)
            mis = mis_weight(pdf_prev, scene.pdf_emitter_direction(si_prev, ds, ~delta_prev))
            Le = beta * mis * ds.emitter.eval(si, active_next)
            active_next &= (depth + 1 < self.max_depth) & si.is_valid() & ~blocked
            # next-event estimation
            active_em = active_next & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
            ds, em_weight = scene.sample_emitter_direction(si, sampler.next_2d(), True,
                                                           active_em)
            active_em &= ds.pdf != 0.0
            wo = si.to_local(ds.d)
            bsdf_em, bsdf_pdf_em = bsdf.eval_pdf(bsdf_ctx, si, wo, active_em)
            mis_em = dr.select(ds.delta, 1, mis_weight(ds.pdf, bsdf_pdf_em))
            Lr = beta * mis_em * bsdf_em * em_weight
            # the next vertex
            bs, bsdf_weight = bsdf.sample(bsdf_ctx, si, sampler.next_1d(), sampler.next_2d(),
                                          active_next)
            L = L + Le + Lr
            ray = si.spawn_ray(si.to_world(bs.wo))
            beta *= bsdf_weight
            si_prev = si
            pdf_prev = bs.pdf
            delta_prev = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
            diffuse_seen |= ~glossy
            depth[si.is_valid()] += 1
            active = active_next & (dr.max(mi.unpolarized_spectrum(beta)) != 0)
        return L, depth != 0, [], L


def render_pixels(integrator, scene, sensor, pixels, spp: int, seed: int):
    """Mean radiance of the film pixels ``pixels`` at ``spp`` samples each (box filter).

    What ``mitsuba.render`` does for a whole film, for a list of its pixels: the sample
    layout, the sampler's seeding and the integrator are Mitsuba's, but the film's size and the
    pixels are data of the kernel, not constants compiled into it, so Dr.Jit compiles one kernel
    per ``spp`` for every window and pixel list.

    Parameters
    ----------
    integrator : RimPath
        The scene's integrator.
    scene, sensor : mitsuba.Scene, mitsuba.Sensor
        The scene and a sensor whose film holds the pixels (box pixel filter, no border).
    pixels : numpy.ndarray
        Flat row-major indices of film pixels (uint32).
    spp : int
        Samples per pixel (a power of 4 for the low-discrepancy sampler).
    seed : int
        The sampler's seed.

    Returns
    -------
    numpy.ndarray
        (len(pixels), 3) float64 mean linear RGB.
    """
    import numpy as np

    film = sensor.film()
    w, h = (int(v) for v in film.crop_size())
    n = len(pixels)
    sampler = sensor.sampler().clone()
    sampler.set_sample_count(int(spp))
    spp = sampler.sample_count()
    sampler.set_samples_per_wavefront(spp)
    sampler.seed(int(seed), n * spp)
    # sample k of pixel i at index i spp + k, as Mitsuba lays out a film's samples
    idx = dr.arange(mi.UInt32, n * spp)
    log_spp = dr.log2i(spp)
    pid = idx >> dr.opaque(mi.UInt32, log_spp) if 1 << log_spp == spp \
        else idx // dr.opaque(mi.UInt32, spp)
    pix = dr.gather(mi.UInt32, mi.UInt32(np.asarray(pixels, dtype=np.uint32)), pid)
    y = pix // dr.opaque(mi.UInt32, w)
    x = pix - y * dr.opaque(mi.UInt32, w)
    pos = mi.Vector2f(mi.Float(x), mi.Float(y)) + sampler.next_2d()
    rel = pos * mi.Vector2f(dr.opaque(mi.Float, 1.0 / w), dr.opaque(mi.Float, 1.0 / h))
    ray, weight = sensor.sample_ray_differential(time=sensor.shutter_open(), sample1=0.0,
                                                 sample2=rel, sample3=mi.Vector2f(0.0))
    L, valid, _, _ = integrator.sample(mode=dr.ADMode.Primal, scene=scene, sampler=sampler,
                                       ray=ray, δL=None, state_in=None, active=mi.Bool(True))
    rgb = dr.select(valid, mi.Color3f(L * weight), 0.0)
    dr.eval(rgb)  # one kernel for the three channels
    # each pixel's spp samples are consecutive: summed block by block in a fixed order (the
    # same bytes every time; a scatter-add's atomics would sum in the threads' order)
    sums = [np.asarray(dr.block_reduce(dr.ReduceOp.Add, rgb[c], spp), dtype=np.float64)
            for c in range(3)]
    return np.stack(sums, axis=1) / spp
