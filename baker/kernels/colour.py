"""Colour constants shared by every stage: linear sRGB / Rec. 709
luminance weights (the light tree's node power, lightcuts' error bound,
the comparisons against the path tracer, auto-exposure)."""
import numpy as np

LUM_R, LUM_G, LUM_B = 0.2126, 0.7152, 0.0722
LUMINANCE = np.array([LUM_R, LUM_G, LUM_B])
