"""Camera calibration from images of a dotted plate traversed along Z.

Every calibration offers the camera protocol of :mod:`ptv.camera_model`.
"""
