"""Colour constants the stages share, plain Python (the NumPy-only stages and the Mitsuba backend read
them without JAX)."""

#: Rec. 709 relative-luminance weights of linear RGB (ITU-R BT.709 §3): the one luminance of the package —
#: the path tracers' lobe choice, the light-leak test, the viewer's maps and ``luminance``.
REC709_LUMA: tuple[float, float, float] = (0.2126, 0.7152, 0.0722)
