#!/usr/bin/python3
"""Writes the label-image fixtures of tests/data/images with nibabel (an independent NIfTI
writer, so Stroma's reader is checked against someone else's files). Debian: python3-nibabel,
python3-numpy. Run from the repository root: /usr/bin/python3 scripts/meshes/write_phantom_images.py

- phantom_1mm.nii.gz, phantom_aniso.nii.gz: an ellipsoid (semi-axes 40, 30, 25 mm; label 1)
  with a spherical inclusion (radius 10 mm, centre (8, 0, 0) mm; label 2), in 1 mm voxels and in
  0.8 x 0.8 x 2 mm voxels; the ellipsoid's centre at the world origin.
- oblique.nii: 7 x 5 x 4 voxels, label = 1 + i + 7 j + 35 k (int16), an sform that rotates by
  30 degrees about z and flips y (an LPS-like reflection), spacing 0.9 x 1.1 x 2.5 mm, origin
  (10, -20, 30) mm; the test checks every voxel's label and the geometry against this affine.
- oblique_qform.nii: the same as a qform (quaternion with qfac -1) and no sform.
"""
import math

import nibabel as nib
import numpy as np


def phantom(spacing, semi=(40.0, 30.0, 25.0), radius=10.0, centre=(8.0, 0.0, 0.0)):
    sp = np.array(spacing, float)
    ext = np.array(semi) + 6.0
    n = np.ceil(2 * ext / sp).astype(int)
    x, y, z = np.meshgrid(*[np.arange(k) * s - e for k, s, e in zip(n, sp, ext)], indexing="ij")
    lab = np.zeros(n, np.uint8)
    lab[(x / semi[0]) ** 2 + (y / semi[1]) ** 2 + (z / semi[2]) ** 2 <= 1] = 1
    lab[(x - centre[0]) ** 2 + (y - centre[1]) ** 2 + (z - centre[2]) ** 2 <= radius ** 2] = 2
    aff = np.diag([sp[0], sp[1], sp[2], 1.0])
    aff[:3, 3] = -ext
    img = nib.Nifti1Image(lab, aff)
    img.header.set_xyzt_units("mm")
    return img


def oblique():
    i, j, k = np.meshgrid(np.arange(7), np.arange(5), np.arange(4), indexing="ij")
    lab = (1 + i + 7 * j + 35 * k).astype(np.int16)
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.diag([1, -1, 1])
    aff = np.eye(4)
    aff[:3, :3] = rot @ np.diag([0.9, 1.1, 2.5])
    aff[:3, 3] = [10, -20, 30]
    img = nib.Nifti1Image(lab, aff)
    img.header.set_xyzt_units("mm")
    return img


if __name__ == "__main__":
    nib.save(phantom((1, 1, 1)), "tests/data/images/phantom_1mm.nii.gz")
    nib.save(phantom((0.8, 0.8, 2)), "tests/data/images/phantom_aniso.nii.gz")
    nib.save(oblique(), "tests/data/images/oblique.nii")
    q = oblique()  # the same geometry as a quaternion (qform, qfac -1 for the flip), no sform
    q.set_qform(q.affine, code=1)
    q.set_sform(None, code=0)
    nib.save(q, "tests/data/images/oblique_qform.nii")
