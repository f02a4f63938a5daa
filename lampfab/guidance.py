"""Post-processing guidance for the made lens: which side faces where, how to finish it,
and how much uneven removal the projection tolerates (``tolerance_study``).

``advice`` returns plain paragraphs (for verify.json); ``html`` renders them with the
tolerance study's table for report.html.  Finishing steps per process come from the
shared fabrication facts ("wet sand 400 -> 2000 grit, then polish; anneal after
machining", makers' reports) unless a sentence says otherwise.
"""

from __future__ import annotations

import html as _html

from .profile import Fabrication, Led
from .room import SECTOR_CENTRE_DEG, SECTOR_WIDTH_DEG

_AXIS = {0.0: "+x", 90.0: "+y", 180.0: "-x", 270.0: "-y"}

_FINISH = {
    "sla": ("Wash and post-cure as the resin maker says. Print it upright on a raft or supports with "
            "a gap under the bore (see the drain check), so no support touches the outer surface. "
            "Wet-sand the outer surface through 400, 600, 800, 1200 and 2000 grit, each grit only until the "
            "previous one's scratches are gone, then polish with a plastic polish; or, instead of the last "
            "grits, dip or brush a thin clear coat of the same resin and cure it: it fills layer lines while "
            "removing nothing."),
    "cnc3": ("Anneal the acrylic after machining (it relieves the cutting stress that otherwise crazes "
             "when polished or glued). Wet-sand only where tool marks or the witness lines between "
             "setups show, through 400, 600, 800, 1200 and 2000 grit, then polish with a plastic polish "
             "or a buffing wheel with fine compound. Flame polishing is for edges: on the optical surface "
             "it melts the relief unevenly."),
    "glass": ("The optics shop grinds and polishes it; give them lens.step and ask for a form error within "
              "the allowance below."),
}
_FINISH["cnc4"] = _FINISH["cnc3"].replace(" or the witness lines between setups", "")


def orientation(wall_names: list[str]) -> str:
    """Which part of the lens lights which wall, in the STL/STEP frame."""
    parts = []
    for name in wall_names:
        c = SECTOR_CENTRE_DEG[name]
        lo, hi = c - SECTOR_WIDTH_DEG / 2, c + SECTOR_WIDTH_DEG / 2
        parts.append(f"the {_AXIS[c]} side (u {lo:g} to {hi:g} deg) lights the {name}"
                     + (" behind the lamp" if name == "floor" else " wall"))
    return ("In lens.stl and lens.step (millimetres, z up, the base on z = 0) " + "; ".join(parts) + ". "
            "Set the lamp with its +y side square to the front wall, the walls at the design's distance. "
            "Mark +y on the base before the part leaves the printer or the machine: the lens looks "
            "much the same from every side.")


# Where the LED's emitter goes and how the design assumes it shines, by its shape.
_MOUNTED = {"disc": "its emitting face level and facing straight up,", "sphere": "its centre",
            "cylinder": "standing upright, its middle",
            "post": "each LED's emitting face upright and square to its wall, their middles"}
_SHINES = {"disc": "it shines up from there as a package on its board does, brightest straight up and nothing "
                   "below the horizon (mounted tilted or lower, the pictures move and darken)",
           "sphere": "it shines evenly in every direction from there", "cylinder": "it shines all round from there",
           "post": "each LED shines level towards its wall from there, brightest straight out (turned on the post, "
                   "the pictures slide sideways)"}


def _fins(led: Led) -> str:
    """The sentence on a post's fins, or nothing."""
    if not led.fin_radius_mm:
        return ""
    return (f" Between the LEDs, on the post, stand matt black fins, {led.fin_radius_mm:g} mm out from the axis "
            f"and {led.fin_height_mm:g} mm tall, centred on them, one at each of the rod's corners (45° from each "
            f"LED): print fins.stl in black (matt, or paint it matt black) and slide it over the "
            f"{led.rod_width_mm:g} mm rod, its fins on the corners, before you glue the LEDs on; the design assumes "
            f"they stop the light that would cross into a neighbour's part of the lens, from the LEDs or reflected "
            f"back across the hollow.")


def paint(paint_json: dict) -> str:
    """The paragraph on painting the faces that light no wall (design.json's lens
    ``black_paint`` and ``painted_u_deg``), or nothing."""
    choice = paint_json.get("black_paint", "none")
    if choice == "none":
        return ""
    back = paint_json.get("painted_u_deg")
    where = "the flat top and the base"
    if back:
        where += f", and the outer surface from u {back[0]:g} to {back[1] % 360:g} deg (the part that faces no wall)"
    return (f"After finishing, paint {where} matt black: mask the rest with tape and use a matt black paint or "
            f"paint marker. They light no wall; painted, they swallow the light the lens reflects inside itself, "
            f"which would otherwise lie as a faint haze over the pictures. verify traced the lens painted so.")


def slots(paint_json: dict, walls: dict | None = None) -> str:
    """The paragraph on filling the black slots (design.json's lens ``slots``), or nothing;
    with verify's ``walls`` figures it says what the lamp would show with them empty."""
    from .slots import Slots

    cut = Slots.from_json(paint_json.get("slots"))
    if cut is None:
        return ""
    where = ", ".join(f"{s.azimuth_deg:g}" for s in cut.slots)
    return (f"Fill the {len(cut.slots)} slots that open in the base ({cut.width_mm:g} mm wide, "
            f"{min(s.from_mm for s in cut.slots):.0f} to {max(s.to_mm for s in cut.slots):.0f} mm out from the axis, "
            f"{cut.top_mm:g} mm deep, at u {where} deg) with black epoxy before you paint the base: flush the resin "
            f"out of them with isopropyl alcohol from a syringe and let them dry; then, the lens standing on its "
            f"top, fill each from its far end with a syringe and a blunt needle, slowly, so that no bubble stays on "
            f"its walls (a clear casting epoxy tinted with a few per cent of black pigment, which wets the resin). "
            f"The black must touch the walls: light reflected inside the lens meets them at about 45°, and behind "
            f"an air gap it would be reflected back whole. verify traced the slots filled so."
            + _slots_empty(walls or {}))


def _slots_empty(walls: dict) -> str:
    """The sentence on the slots left empty, from verify's walls figures, or nothing."""
    traced = {n: f for n, f in walls.items() if "led_ssim_slots_empty" in f}
    if not traced:
        return ""

    def each(key, form):
        return " / ".join(format(f[key], form) for f in traced.values())
    return (f" Traced again with the slots left empty, the walls ({' / '.join(traced)}) score LED SSIM "
            f"{each('led_ssim_slots_empty', '.2f')} instead of {each('led_ssim', '.2f')}, with "
            f"{each('led_ghost_share_slots_empty', '.1%')} of their light reflected inside the lens instead of "
            f"{each('led_ghost_share', '.1%')}: on every picture measured so, lower than a lens made without "
            f"slots.")


def advice(fab: Fabrication, led: Led, wall_names: list[str], light_mm, study: dict,
           paint_json: dict | None = None, walls: dict | None = None) -> list[str]:
    """Plain-text paragraphs: orientation, the LED, finishing, the black paint and
    slots (with verify's ``walls`` figures), the polishing allowance."""
    allowance = study["allowance_mm"] * 1000
    bound = "at least " if study["allowance_at_least"] else ""
    error = study["profile_error_mm"] * 1000
    within = study["profile_error_drop"] <= study["r_drop"]
    out = [
        orientation(wall_names),
        (f"The LED ({led.part}) goes up through the bore in the base ({2 * fab.mount_radius_mm:g} mm across) on "
         f"a stalk, {_MOUNTED[led.shape]} {light_mm[2]:g} mm above the base on the axis; the design assumes "
         f"{_SHINES[led.shape]}, with the size of its profile ({led.name})." + _fins(led)),
        _FINISH[fab.process],
        *[p for p in (paint(paint_json or {}), slots(paint_json or {}, walls)) if p],
        (f"Polishing allowance: uneven removal of up to {bound}{allowance:.0f} um (peak, over patches of "
         f"~{study['correlation_mm']:g} mm) keeps every wall's Pearson r within {study['r_drop']} of the design. "
         f"This profile's surface error, {error:.0f} um, costs r {study['profile_error_drop']:.3f}"
         + (" (within it)." if within else f": more than {study['r_drop']}, so finish more carefully than the "
            f"profile assumes.")
         + " Even removal (the same depth everywhere) does not matter; scratches finer than ~1 mm scatter "
           "light into a haze instead of moving the image, so finish to the last grit."),
    ]
    return out


def html(paragraphs: list[str], study: dict) -> str:
    """The report section: the paragraphs and the tolerance study as a table."""
    walls = list(study["walls"])
    head = "".join(f"<th>r {_html.escape(w)}</th>" for w in walls)
    rows = []
    for k, a in enumerate(study["amplitudes_mm"]):
        drop = study["max_drop"][k]
        cls = "ok" if drop <= study["r_drop"] else "fail"
        cells = "".join(f"<td>{study['walls'][w][k]:.3f}</td>" for w in walls)
        mark = " (profile)" if a == study["profile_error_mm"] else ""
        rows.append(f"<tr><td>{a * 1000:.0f} um{mark}</td>{cells}<td class=\"{cls}\">{drop:.3f}</td></tr>")
    table = (f"<table><tr><th>peak surface error</th>{head}<th>largest drop</th></tr>{''.join(rows)}</table>"
             f"<p class=\"extra\">One smooth random error field (correlation {study['correlation_mm']:g} mm) "
             f"scaled to each peak error; the lens's facets (those of lens.stl, less the bore) traced with {study['photons']:,} photons "
             f"(the same photons at every amplitude), point light. Drops of a few thousandths are the tracer's "
             f"noise at this photon count.</p>")
    return "".join(f"<p>{_html.escape(p)}</p>" for p in paragraphs) + table
