"""mmdetection3d's converter arithmetic, replayed over arrays: a deliberate second implementation.

`nuparquet.geometry` computes what the devkit computes, to rounding. The training index must equal
mmdetection3d's reference infos bit for bit, and those were computed with pyquaternion's float64 operation order
on numpy 1.26 + OpenBLAS kernels (`blas`), then rounded to float32 where the converter rounds. So this folder
repeats quaternions (`quaternions`), transforms and box corners (`transforms`) operation for operation in that
order; nothing outside `nuparquet.index` uses it, and it is not a place for new geometry.
"""
