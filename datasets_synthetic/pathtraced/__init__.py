"""Hard cases from an independent path tracer (Mitsuba 3, optional: ``pip install -e '.[pathtrace]'``).

Modules: ``runtime`` (loading Mitsuba's CPU variant), ``objects`` (a conifer of thin needles and a
uniform fur ball as round curves), ``scene`` (the Mitsuba scene: object, visible room map in furrow's
layout, table top, turntable), ``film`` (rays of a furrow camera and lens: colour, true matte,
z-depth), ``render`` (per-view render cache), ``assemble`` (scan sets and gt/ on disk), ``cases`` (the
named cases of issues 30 and 31).  CLI: ``scripts/hardcases.py`` (``make hardcases``).
"""
