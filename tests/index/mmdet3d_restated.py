"""mmdetection3d's nuScenes converters re-stated line for line, run with the devkit (test-only reference).

- 0.17.x `tools/data_converter/nuscenes_converter.py` (identical in 0.17.0-0.17.3): `create_nuscenes_infos`
  (`_fill_trainval_infos`, `obtain_sensor2top`, `get_available_scenes`) and `export_2d_annotation(mono3d=True)`
  (`get_2d_boxes`, `post_process_coords`, `generate_record`, `box_np_ops.points_cam2img`).
- v1.4.0 `tools/dataset_converters/nuscenes_converter.py` `create_nuscenes_infos` (with its lidarseg lines) and
  `update_infos_to_v2.py` `update_nuscenes_infos` (with `convert_utils.get_nuscenes_2d_boxes` and the
  template/cleanup functions that decide key order).

Only the plumbing differs from the originals: `mmcv`/`mmengine` calls are replaced by what they do (pickle,
`json.dump(obj, f, default=set_default)`, `cv2` decoding for `mmcv.imread`, `os.path.isfile` for
`check_file_exist`); v1.4.0's torch `points_cam2img` is numpy float32 here (the tests compare its two values
with float32 tolerance); the version folder can differ from the version the splits use (`--folder`), as
the reference output's README describes. Shared functions are the same source in both versions.

Run as a script, in a directory where `./data/nuscenes` is the dataroot, as mmdetection3d's tools are run:

    python mmdet3d_restated.py --folder v1.0-synth --version v1.0-trainval --out OUT [--which v017,v14]

It writes OUT/v017/nuscenes_infos_<split>.pkl + nuscenes_infos_<split>_mono3d.coco.json, OUT/v14/v1/ and
OUT/v14/v2/nuscenes_infos_<split>.pkl. It runs with this machine's numpy and BLAS kernels (never pinned): its
floats are this machine's rounding of the converter's products, which the tests compare within that rounding.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import pickle
from collections import OrderedDict
from os import path as osp
from pathlib import Path

import numpy as np

ROOT_PATH = "./data/nuscenes"

nus_categories = ('car', 'truck', 'trailer', 'bus', 'construction_vehicle',
                  'bicycle', 'motorcycle', 'pedestrian', 'traffic_cone',
                  'barrier')

nus_attributes = ('cycle.with_rider', 'cycle.without_rider',
                  'pedestrian.moving', 'pedestrian.standing',
                  'pedestrian.sitting_lying_down', 'vehicle.moving',
                  'vehicle.parked', 'vehicle.stopped', 'None')

# NuScenesDataset.NameMapping (0.17) == convert_utils.NuScenesNameMapping (1.4.0)
NameMapping = {
    'movable_object.barrier': 'barrier',
    'vehicle.bicycle': 'bicycle',
    'vehicle.bus.bendy': 'bus',
    'vehicle.bus.rigid': 'bus',
    'vehicle.car': 'car',
    'vehicle.construction': 'construction_vehicle',
    'vehicle.motorcycle': 'motorcycle',
    'human.pedestrian.adult': 'pedestrian',
    'human.pedestrian.child': 'pedestrian',
    'human.pedestrian.construction_worker': 'pedestrian',
    'human.pedestrian.police_officer': 'pedestrian',
    'movable_object.trafficcone': 'traffic_cone',
    'vehicle.trailer': 'trailer',
    'vehicle.truck': 'truck'
}


def run_restated(work: Path, root: Path, folder: str, version: str, which: str = "v017,v14",
                 max_sweeps: int = 10) -> Path:
    """OUT of this script run on dataroot `root` in a subprocess (numpy and BLAS as this machine has them: its
    floats differ from the index's replay of the reference machine by rounding, docs/CONTRACTS.md), from the
    fresh directory `work` in which ./data/nuscenes is `root` (as mmdetection3d's tools see their data)."""
    import subprocess
    import sys

    (work / "data").mkdir(parents=True)
    (work / "data" / "nuscenes").symlink_to(Path(root).resolve(), target_is_directory=True)
    done = subprocess.run([sys.executable, __file__, "--folder", folder, "--version", version, "--out", "out",
                           "--which", which, "--max-sweeps", str(max_sweeps)],
                          cwd=work, capture_output=True, text=True)
    if done.returncode:
        raise AssertionError(f"the re-stated converter failed:\n{done.stderr[-4000:]}")
    return work / "out"


# --- mmcv / mmengine, as they behave ---------------------------------------------------------------------------

def check_file_exist(filename):
    if not osp.isfile(filename):
        raise FileNotFoundError(f'file "{filename}" does not exist')


def is_filepath(x):
    return isinstance(x, (str, Path))


def imread_shape(path):
    import cv2

    return cv2.imdecode(np.frombuffer(Path(path).read_bytes(), np.uint8), cv2.IMREAD_COLOR).shape


def set_default(obj):
    if isinstance(obj, (set, range)):
        return list(obj)
    elif isinstance(obj, np.ndarray):
        return obj.tolist()
    elif isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f'{type(obj)} is unsupported for json dump')


def dump(obj, file):
    if file.endswith('.json'):
        with open(file, 'w') as f:
            json.dump(obj, f, default=set_default)
    else:
        with open(file, 'wb') as f:
            pickle.dump(obj, f, protocol=2)


def load(file):
    with open(file, 'rb') as f:
        return pickle.load(f)


# --- shared by 0.17.x and v1.4.0 (identical source) -------------------------------------------------------------

def create_nuscenes_infos(fill, root_path, info_prefix, out_dir, folder, version='v1.0-trainval', max_sweeps=10):
    from nuscenes.nuscenes import NuScenes
    nusc = NuScenes(version=folder, dataroot=root_path, verbose=False)
    from nuscenes.utils import splits
    available_vers = ['v1.0-trainval', 'v1.0-test', 'v1.0-mini']
    assert version in available_vers
    if version == 'v1.0-trainval':
        train_scenes = splits.train
        val_scenes = splits.val
    elif version == 'v1.0-test':
        train_scenes = splits.test
        val_scenes = []
    elif version == 'v1.0-mini':
        train_scenes = splits.mini_train
        val_scenes = splits.mini_val
    else:
        raise ValueError('unknown')

    # filter existing scenes.
    available_scenes = get_available_scenes(nusc)
    available_scene_names = [s['name'] for s in available_scenes]
    train_scenes = list(
        filter(lambda x: x in available_scene_names, train_scenes))
    val_scenes = list(filter(lambda x: x in available_scene_names, val_scenes))
    train_scenes = set([
        available_scenes[available_scene_names.index(s)]['token']
        for s in train_scenes
    ])
    val_scenes = set([
        available_scenes[available_scene_names.index(s)]['token']
        for s in val_scenes
    ])

    test = 'test' in version
    train_nusc_infos, val_nusc_infos = fill(
        nusc, train_scenes, val_scenes, test, max_sweeps=max_sweeps)

    metadata = dict(version=version)
    paths = []
    if test:
        data = dict(infos=train_nusc_infos, metadata=metadata)
        info_path = osp.join(out_dir, '{}_infos_test.pkl'.format(info_prefix))
        dump(data, info_path)
        paths.append(info_path)
    else:
        data = dict(infos=train_nusc_infos, metadata=metadata)
        info_path = osp.join(out_dir, '{}_infos_train.pkl'.format(info_prefix))
        dump(data, info_path)
        data['infos'] = val_nusc_infos
        info_val_path = osp.join(out_dir, '{}_infos_val.pkl'.format(info_prefix))
        dump(data, info_val_path)
        paths += [info_path, info_val_path]
    return paths


def get_available_scenes(nusc):
    available_scenes = []
    for scene in nusc.scene:
        scene_token = scene['token']
        scene_rec = nusc.get('scene', scene_token)
        sample_rec = nusc.get('sample', scene_rec['first_sample_token'])
        sd_rec = nusc.get('sample_data', sample_rec['data']['LIDAR_TOP'])
        has_more_frames = True
        scene_not_exist = False
        while has_more_frames:
            lidar_path, boxes, _ = nusc.get_sample_data(sd_rec['token'])
            lidar_path = str(lidar_path)
            if os.getcwd() in lidar_path:
                # path from lyftdataset is absolute path
                lidar_path = lidar_path.split(f'{os.getcwd()}/')[-1]
                # relative path
            if not is_filepath(lidar_path):
                scene_not_exist = True
                break
            else:
                break
        if scene_not_exist:
            continue
        available_scenes.append(scene)
    return available_scenes


def obtain_sensor2top(nusc,
                      sensor_token,
                      l2e_t,
                      l2e_r_mat,
                      e2g_t,
                      e2g_r_mat,
                      sensor_type='lidar'):
    from pyquaternion import Quaternion
    sd_rec = nusc.get('sample_data', sensor_token)
    cs_record = nusc.get('calibrated_sensor',
                         sd_rec['calibrated_sensor_token'])
    pose_record = nusc.get('ego_pose', sd_rec['ego_pose_token'])
    data_path = str(nusc.get_sample_data_path(sd_rec['token']))
    if os.getcwd() in data_path:  # path from lyftdataset is absolute path
        data_path = data_path.split(f'{os.getcwd()}/')[-1]  # relative path
    sweep = {
        'data_path': data_path,
        'type': sensor_type,
        'sample_data_token': sd_rec['token'],
        'sensor2ego_translation': cs_record['translation'],
        'sensor2ego_rotation': cs_record['rotation'],
        'ego2global_translation': pose_record['translation'],
        'ego2global_rotation': pose_record['rotation'],
        'timestamp': sd_rec['timestamp']
    }
    l2e_r_s = sweep['sensor2ego_rotation']
    l2e_t_s = sweep['sensor2ego_translation']
    e2g_r_s = sweep['ego2global_rotation']
    e2g_t_s = sweep['ego2global_translation']

    # obtain the RT from sensor to Top LiDAR
    # sweep->ego->global->ego'->lidar
    l2e_r_s_mat = Quaternion(l2e_r_s).rotation_matrix
    e2g_r_s_mat = Quaternion(e2g_r_s).rotation_matrix
    R = (l2e_r_s_mat.T @ e2g_r_s_mat.T) @ (
        np.linalg.inv(e2g_r_mat).T @ np.linalg.inv(l2e_r_mat).T)
    T = (l2e_t_s @ e2g_r_s_mat.T + e2g_t_s) @ (
        np.linalg.inv(e2g_r_mat).T @ np.linalg.inv(l2e_r_mat).T)
    T -= e2g_t @ (np.linalg.inv(e2g_r_mat).T @ np.linalg.inv(l2e_r_mat).T
                  ) + l2e_t @ np.linalg.inv(l2e_r_mat).T
    sweep['sensor2lidar_rotation'] = R.T  # points @ R.T + T
    sweep['sensor2lidar_translation'] = T
    return sweep


def _fill_trainval_infos(nusc, train_scenes, val_scenes, test=False, max_sweeps=10, *, legacy: bool):
    """0.17.x's `_fill_trainval_infos` (`legacy`) or v1.4.0's: the two differ in exactly the lines marked."""
    from pyquaternion import Quaternion
    train_nusc_infos = []
    val_nusc_infos = []

    for sample in nusc.sample:
        lidar_token = sample['data']['LIDAR_TOP']
        sd_rec = nusc.get('sample_data', sample['data']['LIDAR_TOP'])
        cs_record = nusc.get('calibrated_sensor',
                             sd_rec['calibrated_sensor_token'])
        pose_record = nusc.get('ego_pose', sd_rec['ego_pose_token'])
        lidar_path, boxes, _ = nusc.get_sample_data(lidar_token)

        check_file_exist(lidar_path)

        if legacy:  # 0.17
            info = {
                'lidar_path': lidar_path,
                'token': sample['token'],
                'sweeps': [],
                'cams': dict(),
                'lidar2ego_translation': cs_record['translation'],
                'lidar2ego_rotation': cs_record['rotation'],
                'ego2global_translation': pose_record['translation'],
                'ego2global_rotation': pose_record['rotation'],
                'timestamp': sample['timestamp'],
            }
        else:  # v1.4.0
            info = {
                'lidar_path': lidar_path,
                'num_features': 5,
                'token': sample['token'],
                'sweeps': [],
                'cams': dict(),
                'lidar2ego_translation': cs_record['translation'],
                'lidar2ego_rotation': cs_record['rotation'],
                'ego2global_translation': pose_record['translation'],
                'ego2global_rotation': pose_record['rotation'],
                'timestamp': sample['timestamp'],
            }

        l2e_r = info['lidar2ego_rotation']
        l2e_t = info['lidar2ego_translation']
        e2g_r = info['ego2global_rotation']
        e2g_t = info['ego2global_translation']
        l2e_r_mat = Quaternion(l2e_r).rotation_matrix
        e2g_r_mat = Quaternion(e2g_r).rotation_matrix

        # obtain 6 image's information per frame
        camera_types = [
            'CAM_FRONT',
            'CAM_FRONT_RIGHT',
            'CAM_FRONT_LEFT',
            'CAM_BACK',
            'CAM_BACK_LEFT',
            'CAM_BACK_RIGHT',
        ]
        for cam in camera_types:
            cam_token = sample['data'][cam]
            cam_path, _, cam_intrinsic = nusc.get_sample_data(cam_token)
            cam_info = obtain_sensor2top(nusc, cam_token, l2e_t, l2e_r_mat,
                                         e2g_t, e2g_r_mat, cam)
            cam_info.update(cam_intrinsic=cam_intrinsic)
            info['cams'].update({cam: cam_info})

        # obtain sweeps for a single key-frame
        sd_rec = nusc.get('sample_data', sample['data']['LIDAR_TOP'])
        sweeps = []
        while len(sweeps) < max_sweeps:
            if not sd_rec['prev'] == '':
                sweep = obtain_sensor2top(nusc, sd_rec['prev'], l2e_t,
                                          l2e_r_mat, e2g_t, e2g_r_mat, 'lidar')
                sweeps.append(sweep)
                sd_rec = nusc.get('sample_data', sd_rec['prev'])
            else:
                break
        info['sweeps'] = sweeps
        # obtain annotation
        if not test:
            annotations = [
                nusc.get('sample_annotation', token)
                for token in sample['anns']
            ]
            locs = np.array([b.center for b in boxes]).reshape(-1, 3)
            dims = np.array([b.wlh for b in boxes]).reshape(-1, 3)
            rots = np.array([b.orientation.yaw_pitch_roll[0]
                             for b in boxes]).reshape(-1, 1)
            velocity = np.array(
                [nusc.box_velocity(token)[:2] for token in sample['anns']])
            valid_flag = np.array(
                [(anno['num_lidar_pts'] + anno['num_radar_pts']) > 0
                 for anno in annotations],
                dtype=bool).reshape(-1)
            # convert velo from global to lidar
            for i in range(len(boxes)):
                velo = np.array([*velocity[i], 0.0])
                velo = velo @ np.linalg.inv(e2g_r_mat).T @ np.linalg.inv(
                    l2e_r_mat).T
                velocity[i] = velo[:2]

            names = [b.name for b in boxes]
            for i in range(len(names)):
                if names[i] in NameMapping:
                    names[i] = NameMapping[names[i]]
            names = np.array(names)
            if legacy:  # 0.17: we need to convert rot to SECOND format.
                gt_boxes = np.concatenate([locs, dims, -rots - np.pi / 2], axis=1)
            else:  # v1.4.0: x_size, y_size, z_size (l, w, h)
                gt_boxes = np.concatenate([locs, dims[:, [1, 0, 2]], rots], axis=1)
            assert len(gt_boxes) == len(
                annotations), f'{len(gt_boxes)}, {len(annotations)}'
            info['gt_boxes'] = gt_boxes
            info['gt_names'] = names
            info['gt_velocity'] = velocity.reshape(-1, 2)
            info['num_lidar_pts'] = np.array(
                [a['num_lidar_pts'] for a in annotations])
            info['num_radar_pts'] = np.array(
                [a['num_radar_pts'] for a in annotations])
            info['valid_flag'] = valid_flag

            if not legacy and 'lidarseg' in nusc.table_names:  # v1.4.0 only
                info['pts_semantic_mask_path'] = osp.join(
                    nusc.dataroot,
                    nusc.get('lidarseg', lidar_token)['filename'])

        if sample['scene_token'] in train_scenes:
            train_nusc_infos.append(info)
        else:
            val_nusc_infos.append(info)

    return train_nusc_infos, val_nusc_infos


def fill_v017(*args, **kwargs):
    return _fill_trainval_infos(*args, **kwargs, legacy=True)


def fill_v14(*args, **kwargs):
    return _fill_trainval_infos(*args, **kwargs, legacy=False)


def _box_in_camera(nusc, ann_rec, pose_rec, cs_rec):
    """The lines both versions share: the annotation's box moved into the camera frame."""
    from pyquaternion import Quaternion
    # Get the box in global coordinates.
    box = nusc.get_box(ann_rec['token'])

    # Move them to the ego-pose frame.
    box.translate(-np.array(pose_rec['translation']))
    box.rotate(Quaternion(pose_rec['rotation']).inverse)

    # Move them to the calibrated sensor frame.
    box.translate(-np.array(cs_rec['translation']))
    box.rotate(Quaternion(cs_rec['rotation']).inverse)
    return box


def _projected_corners(box, camera_intrinsic):
    from nuscenes.utils.geometry_utils import view_points
    # Filter out the corners that are not in front of the calibrated
    # sensor.
    corners_3d = box.corners()
    in_front = np.argwhere(corners_3d[2, :] > 0).flatten()
    corners_3d = corners_3d[:, in_front]

    # Project 3d box to 2d.
    return view_points(corners_3d, camera_intrinsic, True).T[:, :2].tolist()


def _camera_velocity(nusc, box, pose_rec, cs_rec):
    from pyquaternion import Quaternion
    global_velo2d = nusc.box_velocity(box.token)[:2]
    global_velo3d = np.array([*global_velo2d, 0.0])
    e2g_r_mat = Quaternion(pose_rec['rotation']).rotation_matrix
    c2e_r_mat = Quaternion(cs_rec['rotation']).rotation_matrix
    cam_velo3d = global_velo3d @ np.linalg.inv(
        e2g_r_mat).T @ np.linalg.inv(c2e_r_mat).T
    return cam_velo3d[0::2].tolist()


# --- 0.17.x: export_2d_annotation and its helpers ----------------------------------------------------------------

def points_cam2img_v017(points_3d, proj_mat, with_depth=False):
    """mmdet3d/core/bbox/box_np_ops.py (0.17.x): numpy, float64."""
    points_shape = list(points_3d.shape)
    points_shape[-1] = 1

    assert len(proj_mat.shape) == 2, 'The dimension of the projection'\
        f' matrix should be 2 instead of {len(proj_mat.shape)}.'
    d1, d2 = proj_mat.shape[:2]
    assert (d1 == 3 and d2 == 3) or (d1 == 3 and d2 == 4) or (
        d1 == 4 and d2 == 4), 'The shape of the projection matrix'\
        f' ({d1}*{d2}) is not supported.'
    if d1 == 3:
        proj_mat_expanded = np.eye(4, dtype=proj_mat.dtype)
        proj_mat_expanded[:d1, :d2] = proj_mat
        proj_mat = proj_mat_expanded

    points_4 = np.concatenate([points_3d, np.ones(points_shape)], axis=-1)
    point_2d = points_4 @ proj_mat.T
    point_2d_res = point_2d[..., :2] / point_2d[..., 2:3]

    if with_depth:
        points_2d_depth = np.concatenate([point_2d_res, point_2d[..., 2:3]],
                                         axis=-1)
        return points_2d_depth

    return point_2d_res


def export_2d_annotation_v017(root_path, info_path, folder, mono3d=True):
    from nuscenes.nuscenes import NuScenes
    # get bbox annotations for camera
    camera_types = [
        'CAM_FRONT',
        'CAM_FRONT_RIGHT',
        'CAM_FRONT_LEFT',
        'CAM_BACK',
        'CAM_BACK_LEFT',
        'CAM_BACK_RIGHT',
    ]
    nusc_infos = load(info_path)['infos']
    nusc = NuScenes(version=folder, dataroot=root_path, verbose=False)
    # info_2d_list = []
    cat2Ids = [
        dict(id=nus_categories.index(cat_name), name=cat_name)
        for cat_name in nus_categories
    ]
    coco_ann_id = 0
    coco_2d_dict = dict(annotations=[], images=[], categories=cat2Ids)
    for info in nusc_infos:
        for cam in camera_types:
            cam_info = info['cams'][cam]
            coco_infos = get_2d_boxes_v017(
                nusc,
                cam_info['sample_data_token'],
                visibilities=['', '1', '2', '3', '4'],
                mono3d=mono3d)
            (height, width, _) = imread_shape(cam_info['data_path'])
            coco_2d_dict['images'].append(
                dict(
                    file_name=cam_info['data_path'].split('data/nuscenes/')
                    [-1],
                    id=cam_info['sample_data_token'],
                    token=info['token'],
                    cam2ego_rotation=cam_info['sensor2ego_rotation'],
                    cam2ego_translation=cam_info['sensor2ego_translation'],
                    ego2global_rotation=info['ego2global_rotation'],
                    ego2global_translation=info['ego2global_translation'],
                    cam_intrinsic=cam_info['cam_intrinsic'],
                    width=width,
                    height=height))
            for coco_info in coco_infos:
                if coco_info is None:
                    continue
                # add an empty key for coco format
                coco_info['segmentation'] = []
                coco_info['id'] = coco_ann_id
                coco_2d_dict['annotations'].append(coco_info)
                coco_ann_id += 1
    if mono3d:
        json_prefix = f'{info_path[:-4]}_mono3d'
    else:
        json_prefix = f'{info_path[:-4]}'
    dump(coco_2d_dict, f'{json_prefix}.coco.json')
    return coco_2d_dict


def get_2d_boxes_v017(nusc, sample_data_token, visibilities, mono3d=True):
    # Get the sample data and the sample corresponding to that sample data.
    sd_rec = nusc.get('sample_data', sample_data_token)

    assert sd_rec[
        'sensor_modality'] == 'camera', 'Error: get_2d_boxes only works' \
        ' for camera sample_data!'
    if not sd_rec['is_key_frame']:
        raise ValueError(
            'The 2D re-projections are available only for keyframes.')

    s_rec = nusc.get('sample', sd_rec['sample_token'])

    # Get the calibrated sensor and ego pose
    # record to get the transformation matrices.
    cs_rec = nusc.get('calibrated_sensor', sd_rec['calibrated_sensor_token'])
    pose_rec = nusc.get('ego_pose', sd_rec['ego_pose_token'])
    camera_intrinsic = np.array(cs_rec['camera_intrinsic'])

    # Get all the annotation with the specified visibilties.
    ann_recs = [
        nusc.get('sample_annotation', token) for token in s_rec['anns']
    ]
    ann_recs = [
        ann_rec for ann_rec in ann_recs
        if (ann_rec['visibility_token'] in visibilities)
    ]

    repro_recs = []

    for ann_rec in ann_recs:
        # Augment sample_annotation with token information.
        ann_rec['sample_annotation_token'] = ann_rec['token']
        ann_rec['sample_data_token'] = sample_data_token

        box = _box_in_camera(nusc, ann_rec, pose_rec, cs_rec)
        corner_coords = _projected_corners(box, camera_intrinsic)

        # Keep only corners that fall within the image.
        final_coords = post_process_coords_v017(corner_coords)

        # Skip if the convex hull of the re-projected corners
        # does not intersect the image canvas.
        if final_coords is None:
            continue
        else:
            min_x, min_y, max_x, max_y = final_coords

        # Generate dictionary record to be included in the .json file.
        repro_rec = generate_record_v017(ann_rec, min_x, min_y, max_x, max_y,
                                         sample_data_token, sd_rec['filename'])

        # If mono3d=True, add 3D annotations in camera coordinates
        if mono3d and (repro_rec is not None):
            loc = box.center.tolist()

            dim = box.wlh
            dim[[0, 1, 2]] = dim[[1, 2, 0]]  # convert wlh to our lhw
            dim = dim.tolist()

            rot = box.orientation.yaw_pitch_roll[0]
            rot = [-rot]  # convert the rot to our cam coordinate

            velo = _camera_velocity(nusc, box, pose_rec, cs_rec)

            repro_rec['bbox_cam3d'] = loc + dim + rot
            repro_rec['velo_cam3d'] = velo

            center3d = np.array(loc).reshape([1, 3])
            center2d = points_cam2img_v017(
                center3d, camera_intrinsic, with_depth=True)
            repro_rec['center2d'] = center2d.squeeze().tolist()
            # normalized center2D + depth
            # if samples with depth < 0 will be removed
            if repro_rec['center2d'][2] <= 0:
                continue

            ann_token = nusc.get('sample_annotation',
                                 box.token)['attribute_tokens']
            if len(ann_token) == 0:
                attr_name = 'None'
            else:
                attr_name = nusc.get('attribute', ann_token[0])['name']
            attr_id = nus_attributes.index(attr_name)
            repro_rec['attribute_name'] = attr_name
            repro_rec['attribute_id'] = attr_id

        repro_recs.append(repro_rec)

    return repro_recs


def post_process_coords_v017(corner_coords, imsize=(1600, 900)):
    from shapely.geometry import MultiPoint, box
    polygon_from_2d_box = MultiPoint(corner_coords).convex_hull
    img_canvas = box(0, 0, imsize[0], imsize[1])

    if polygon_from_2d_box.intersects(img_canvas):
        img_intersection = polygon_from_2d_box.intersection(img_canvas)
        intersection_coords = np.array(
            [coord for coord in img_intersection.exterior.coords])

        min_x = min(intersection_coords[:, 0])
        min_y = min(intersection_coords[:, 1])
        max_x = max(intersection_coords[:, 0])
        max_y = max(intersection_coords[:, 1])

        return min_x, min_y, max_x, max_y
    else:
        return None


def generate_record_v017(ann_rec, x1, y1, x2, y2, sample_data_token, filename):
    repro_rec = OrderedDict()
    repro_rec['sample_data_token'] = sample_data_token
    coco_rec = dict()

    relevant_keys = [
        'attribute_tokens',
        'category_name',
        'instance_token',
        'next',
        'num_lidar_pts',
        'num_radar_pts',
        'prev',
        'sample_annotation_token',
        'sample_data_token',
        'visibility_token',
    ]

    for key, value in ann_rec.items():
        if key in relevant_keys:
            repro_rec[key] = value

    repro_rec['bbox_corners'] = [x1, y1, x2, y2]
    repro_rec['filename'] = filename

    coco_rec['file_name'] = filename
    coco_rec['image_id'] = sample_data_token
    coco_rec['area'] = (y2 - y1) * (x2 - x1)

    if repro_rec['category_name'] not in NameMapping:
        return None
    cat_name = NameMapping[repro_rec['category_name']]
    coco_rec['category_name'] = cat_name
    coco_rec['category_id'] = nus_categories.index(cat_name)
    coco_rec['bbox'] = [x1, y1, x2 - x1, y2 - y1]
    coco_rec['iscrowd'] = 0

    return coco_rec


# --- v1.4.0: update_infos_to_v2.update_nuscenes_infos and what it calls ------------------------------------------

def convert_quaternion_to_matrix(quaternion, translation=None):
    from pyquaternion import Quaternion
    result = np.eye(4)
    result[:3, :3] = Quaternion(quaternion).rotation_matrix
    if translation is not None:
        result[:3, 3] = np.array(translation)
    return result.astype(np.float32).tolist()


def points_cam2img_v14(points_3d, proj_mat, with_depth=False):
    """mmdet3d/structures/bbox_3d/utils.py: torch, through array_converter's float32 tensors (numpy float32
    here: the same operations, the last bit may differ)."""
    points_3d = points_3d.astype(np.float32)
    proj_mat = proj_mat.astype(np.float32)
    points_shape = list(points_3d.shape)
    points_shape[-1] = 1
    d1, d2 = proj_mat.shape[:2]
    if d1 == 3:
        proj_mat_expanded = np.eye(4, dtype=proj_mat.dtype)
        proj_mat_expanded[:d1, :d2] = proj_mat
        proj_mat = proj_mat_expanded
    points_4 = np.concatenate([points_3d, np.ones(points_shape, np.float32)], axis=-1)
    point_2d = points_4 @ proj_mat.T
    point_2d_res = point_2d[..., :2] / point_2d[..., 2:3]
    if with_depth:
        point_2d_res = np.concatenate([point_2d_res, point_2d[..., 2:3]], axis=-1)
    return point_2d_res


def post_process_coords_v14(corner_coords, imsize=(1600, 900)):
    from shapely.geometry import MultiPoint, box
    from shapely.geometry.polygon import Polygon
    polygon_from_2d_box = MultiPoint(corner_coords).convex_hull
    img_canvas = box(0, 0, imsize[0], imsize[1])

    if polygon_from_2d_box.intersects(img_canvas):
        img_intersection = polygon_from_2d_box.intersection(img_canvas)
        if isinstance(img_intersection, Polygon):
            intersection_coords = np.array(
                [coord for coord in img_intersection.exterior.coords])
            min_x = min(intersection_coords[:, 0])
            min_y = min(intersection_coords[:, 1])
            max_x = max(intersection_coords[:, 0])
            max_y = max(intersection_coords[:, 1])
            return min_x, min_y, max_x, max_y
        else:
            return None
    else:
        return None


def generate_record_v14(ann_rec, x1, y1, x2, y2, dataset):
    """convert_utils.generate_record (its nuscenes branch)."""
    if dataset == 'nuscenes':
        cat_name = ann_rec['category_name']
        if cat_name not in NameMapping:
            return None
        else:
            cat_name = NameMapping[cat_name]
            categories = nus_categories
    else:
        raise NotImplementedError('Unsupported dataset!')

    rec = dict()
    rec['bbox_label'] = categories.index(cat_name)
    rec['bbox_label_3d'] = rec['bbox_label']
    rec['bbox'] = [x1, y1, x2, y2]
    rec['bbox_3d_isvalid'] = True

    return rec


def get_nuscenes_2d_boxes(nusc, sample_data_token, visibilities):
    sd_rec = nusc.get('sample_data', sample_data_token)
    assert sd_rec['sensor_modality'] == 'camera'
    if not sd_rec['is_key_frame']:
        raise ValueError('The 2D re-projections are available only for keyframes.')
    s_rec = nusc.get('sample', sd_rec['sample_token'])
    cs_rec = nusc.get('calibrated_sensor', sd_rec['calibrated_sensor_token'])
    pose_rec = nusc.get('ego_pose', sd_rec['ego_pose_token'])
    camera_intrinsic = np.array(cs_rec['camera_intrinsic'])
    ann_recs = [nusc.get('sample_annotation', token) for token in s_rec['anns']]
    ann_recs = [ann_rec for ann_rec in ann_recs if (ann_rec['visibility_token'] in visibilities)]
    repro_recs = []
    for ann_rec in ann_recs:
        ann_rec['sample_annotation_token'] = ann_rec['token']
        ann_rec['sample_data_token'] = sample_data_token
        box = _box_in_camera(nusc, ann_rec, pose_rec, cs_rec)
        corner_coords = _projected_corners(box, camera_intrinsic)
        final_coords = post_process_coords_v14(corner_coords)
        if final_coords is None:
            continue
        else:
            min_x, min_y, max_x, max_y = final_coords
        repro_rec = generate_record_v14(ann_rec, min_x, min_y, max_x, max_y, 'nuscenes')
        # if repro_rec is None, we do not append it into repre_recs
        if repro_rec is not None:
            loc = box.center.tolist()

            dim = box.wlh
            dim[[0, 1, 2]] = dim[[1, 2, 0]]  # convert wlh to our lhw
            dim = dim.tolist()

            rot = box.orientation.yaw_pitch_roll[0]
            rot = [-rot]  # convert the rot to our cam coordinate

            velo = _camera_velocity(nusc, box, pose_rec, cs_rec)

            repro_rec['bbox_3d'] = loc + dim + rot
            repro_rec['velocity'] = velo

            center_3d = np.array(loc).reshape([1, 3])
            center_2d_with_depth = points_cam2img_v14(center_3d, camera_intrinsic, with_depth=True)
            center_2d_with_depth = center_2d_with_depth.squeeze().tolist()
            repro_rec['center_2d'] = center_2d_with_depth[:2]
            repro_rec['depth'] = center_2d_with_depth[2]
            # normalized center2D + depth
            # if samples with depth < 0 will be removed
            if repro_rec['depth'] <= 0:
                continue

            ann_token = nusc.get('sample_annotation', box.token)['attribute_tokens']
            if len(ann_token) == 0:
                attr_name = 'None'
            else:
                attr_name = nusc.get('attribute', ann_token[0])['name']
            attr_id = nus_attributes.index(attr_name)
            # repro_rec['attribute_name'] = attr_name
            repro_rec['attr_label'] = attr_id

            repro_recs.append(repro_rec)

    return repro_recs


def get_empty_instance():
    return dict(bbox=None, bbox_label=None, bbox_3d=None, bbox_3d_isvalid=None, bbox_label_3d=None, depth=None,
                center_2d=None, attr_label=None, num_lidar_pts=None, num_radar_pts=None, difficulty=None,
                unaligned_bbox_3d=None)


def get_empty_multicamera_instances(camera_types):
    cam_instance = dict()
    for cam_type in camera_types:
        cam_instance[cam_type] = None
    return cam_instance


def get_empty_lidar_points():
    return dict(num_pts_feats=None, lidar_path=None, lidar2ego=None)


def get_empty_radar_points():
    return dict(num_pts_feats=None, radar_path=None, radar2ego=None)


def get_empty_img_info():
    return dict(img_path=None, height=None, width=None, depth_map=None, cam2img=None, lidar2img=None, cam2ego=None)


def get_single_image_sweep(camera_types):
    single_image_sweep = dict(timestamp=None, ego2global=None)
    images = dict()
    for cam_type in camera_types:
        images[cam_type] = get_empty_img_info()
    single_image_sweep['images'] = images
    return single_image_sweep


def get_single_lidar_sweep():
    return dict(timestamp=None, ego2global=None, lidar_points=get_empty_lidar_points())


def get_empty_standard_data_info(camera_types=['CAM0', 'CAM1', 'CAM2', 'CAM3', 'CAM4']):
    data_info = dict(
        sample_idx=None,
        token=None,
        **get_single_image_sweep(camera_types),
        lidar_points=get_empty_lidar_points(),
        radar_points=get_empty_radar_points(),
        image_sweeps=[],
        lidar_sweeps=[],
        instances=[],
        instances_ignore=[],
        pts_semantic_mask_path=None,
        pts_instance_mask_path=None)
    return data_info


def clear_instance_unused_keys(instance):
    keys = list(instance.keys())
    for k in keys:
        if instance[k] is None:
            del instance[k]
    return instance


def clear_data_info_unused_keys(data_info):
    keys = list(data_info.keys())
    empty_flag = True
    for key in keys:
        # we allow no annotations in datainfo
        if key in ['instances', 'cam_sync_instances', 'cam_instances']:
            empty_flag = False
            continue
        if isinstance(data_info[key], list):
            if len(data_info[key]) == 0:
                del data_info[key]
            else:
                empty_flag = False
        elif data_info[key] is None:
            del data_info[key]
        elif isinstance(data_info[key], dict):
            _, sub_empty_flag = clear_data_info_unused_keys(data_info[key])
            if sub_empty_flag is False:
                empty_flag = False
            else:
                # sub field is empty
                del data_info[key]
        else:
            empty_flag = False

    return data_info, empty_flag


def generate_nuscenes_camera_instances(info, nusc):
    camera_types = ['CAM_FRONT', 'CAM_FRONT_RIGHT', 'CAM_FRONT_LEFT', 'CAM_BACK', 'CAM_BACK_LEFT', 'CAM_BACK_RIGHT']
    empty_multicamera_instance = get_empty_multicamera_instances(camera_types)
    for cam in camera_types:
        cam_info = info['cams'][cam]
        # list[dict]
        ann_infos = get_nuscenes_2d_boxes(nusc, cam_info['sample_data_token'], visibilities=['', '1', '2', '3', '4'])
        empty_multicamera_instance[cam] = ann_infos
    return empty_multicamera_instance


def update_nuscenes_infos(pkl_path, out_dir, folder):
    from nuscenes.nuscenes import NuScenes
    camera_types = ['CAM_FRONT', 'CAM_FRONT_RIGHT', 'CAM_FRONT_LEFT', 'CAM_BACK', 'CAM_BACK_LEFT', 'CAM_BACK_RIGHT']
    data_list = load(pkl_path)
    METAINFO = {
        'classes':
        ('car', 'truck', 'trailer', 'bus', 'construction_vehicle', 'bicycle',
         'motorcycle', 'pedestrian', 'traffic_cone', 'barrier'),
    }
    nusc = NuScenes(version=folder, dataroot='./data/nuscenes', verbose=False)

    converted_list = []
    for i, ori_info_dict in enumerate(data_list['infos']):
        temp_data_info = get_empty_standard_data_info(
            camera_types=camera_types)
        temp_data_info['sample_idx'] = i
        temp_data_info['token'] = ori_info_dict['token']
        temp_data_info['ego2global'] = convert_quaternion_to_matrix(
            ori_info_dict['ego2global_rotation'],
            ori_info_dict['ego2global_translation'])
        temp_data_info['lidar_points']['num_pts_feats'] = ori_info_dict.get(
            'num_features', 5)
        temp_data_info['lidar_points']['lidar_path'] = Path(
            ori_info_dict['lidar_path']).name
        temp_data_info['lidar_points'][
            'lidar2ego'] = convert_quaternion_to_matrix(
                ori_info_dict['lidar2ego_rotation'],
                ori_info_dict['lidar2ego_translation'])
        # bc-breaking: Timestamp has divided 1e6 in pkl infos.
        temp_data_info['timestamp'] = ori_info_dict['timestamp'] / 1e6
        for ori_sweep in ori_info_dict['sweeps']:
            temp_lidar_sweep = get_single_lidar_sweep()
            temp_lidar_sweep['lidar_points'][
                'lidar2ego'] = convert_quaternion_to_matrix(
                    ori_sweep['sensor2ego_rotation'],
                    ori_sweep['sensor2ego_translation'])
            temp_lidar_sweep['ego2global'] = convert_quaternion_to_matrix(
                ori_sweep['ego2global_rotation'],
                ori_sweep['ego2global_translation'])
            lidar2sensor = np.eye(4)
            rot = ori_sweep['sensor2lidar_rotation']
            trans = ori_sweep['sensor2lidar_translation']
            lidar2sensor[:3, :3] = rot.T
            lidar2sensor[:3, 3:4] = -1 * np.matmul(rot.T, trans.reshape(3, 1))
            temp_lidar_sweep['lidar_points'][
                'lidar2sensor'] = lidar2sensor.astype(np.float32).tolist()
            temp_lidar_sweep['timestamp'] = ori_sweep['timestamp'] / 1e6
            temp_lidar_sweep['lidar_points']['lidar_path'] = ori_sweep[
                'data_path']
            temp_lidar_sweep['sample_data_token'] = ori_sweep[
                'sample_data_token']
            temp_data_info['lidar_sweeps'].append(temp_lidar_sweep)
        temp_data_info['images'] = {}
        for cam in ori_info_dict['cams']:
            empty_img_info = get_empty_img_info()
            empty_img_info['img_path'] = Path(
                ori_info_dict['cams'][cam]['data_path']).name
            empty_img_info['cam2img'] = ori_info_dict['cams'][cam][
                'cam_intrinsic'].tolist()
            empty_img_info['sample_data_token'] = ori_info_dict['cams'][cam][
                'sample_data_token']
            # bc-breaking: Timestamp has divided 1e6 in pkl infos.
            empty_img_info[
                'timestamp'] = ori_info_dict['cams'][cam]['timestamp'] / 1e6
            empty_img_info['cam2ego'] = convert_quaternion_to_matrix(
                ori_info_dict['cams'][cam]['sensor2ego_rotation'],
                ori_info_dict['cams'][cam]['sensor2ego_translation'])
            lidar2sensor = np.eye(4)
            rot = ori_info_dict['cams'][cam]['sensor2lidar_rotation']
            trans = ori_info_dict['cams'][cam]['sensor2lidar_translation']
            lidar2sensor[:3, :3] = rot.T
            lidar2sensor[:3, 3:4] = -1 * np.matmul(rot.T, trans.reshape(3, 1))
            empty_img_info['lidar2cam'] = lidar2sensor.astype(
                np.float32).tolist()
            temp_data_info['images'][cam] = empty_img_info
        ignore_class_name = set()
        if 'gt_boxes' in ori_info_dict:
            num_instances = ori_info_dict['gt_boxes'].shape[0]
            for i in range(num_instances):
                empty_instance = get_empty_instance()
                empty_instance['bbox_3d'] = ori_info_dict['gt_boxes'][
                    i, :].tolist()
                if ori_info_dict['gt_names'][i] in METAINFO['classes']:
                    empty_instance['bbox_label'] = METAINFO['classes'].index(
                        ori_info_dict['gt_names'][i])
                else:
                    ignore_class_name.add(ori_info_dict['gt_names'][i])
                    empty_instance['bbox_label'] = -1
                empty_instance['bbox_label_3d'] = copy.deepcopy(
                    empty_instance['bbox_label'])
                empty_instance['velocity'] = ori_info_dict['gt_velocity'][
                    i, :].tolist()
                empty_instance['num_lidar_pts'] = ori_info_dict[
                    'num_lidar_pts'][i]
                empty_instance['num_radar_pts'] = ori_info_dict[
                    'num_radar_pts'][i]
                empty_instance['bbox_3d_isvalid'] = ori_info_dict[
                    'valid_flag'][i]
                empty_instance = clear_instance_unused_keys(empty_instance)
                temp_data_info['instances'].append(empty_instance)
            temp_data_info[
                'cam_instances'] = generate_nuscenes_camera_instances(
                    ori_info_dict, nusc)
        if 'pts_semantic_mask_path' in ori_info_dict:
            temp_data_info['pts_semantic_mask_path'] = Path(
                ori_info_dict['pts_semantic_mask_path']).name
        temp_data_info, _ = clear_data_info_unused_keys(temp_data_info)
        converted_list.append(temp_data_info)
    pkl_name = Path(pkl_path).name
    out_path = osp.join(out_dir, pkl_name)

    metainfo = dict()
    metainfo['categories'] = {k: i for i, k in enumerate(METAINFO['classes'])}
    if ignore_class_name:
        for ignore_class in ignore_class_name:
            metainfo['categories'][ignore_class] = -1
    metainfo['dataset'] = 'nuscenes'
    metainfo['version'] = data_list['metadata']['version']
    metainfo['info_version'] = '1.1'
    converted_data_info = dict(metainfo=metainfo, data_list=converted_list)

    dump(converted_data_info, out_path)


# --- the two tool runs ------------------------------------------------------------------------------------------

def run(folder: str, version: str, out: Path, which: tuple[str, ...], max_sweeps: int = 10) -> None:
    if "v017" in which:  # tools/create_data.py nuscenes_data_prep of 0.17.x, GT database left out
        target = out / "v017"
        target.mkdir(parents=True)
        for info_path in create_nuscenes_infos(fill_v017, ROOT_PATH, "nuscenes", str(target), folder, version,
                                               max_sweeps):
            export_2d_annotation_v017(ROOT_PATH, info_path, folder)
    if "v14" in which:  # create_data.py then update_infos_to_v2.py of v1.4.0
        v1, v2 = out / "v14" / "v1", out / "v14" / "v2"
        v1.mkdir(parents=True)
        v2.mkdir(parents=True)
        for info_path in create_nuscenes_infos(fill_v14, ROOT_PATH, "nuscenes", str(v1), folder, version, max_sweeps):
            if load(info_path)['infos']:  # an empty split stops update_nuscenes_infos (ignore_class_name unbound)
                update_nuscenes_infos(info_path, str(v2), folder)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--folder", required=True)
    parser.add_argument("--version", required=True)
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--which", default="v017,v14")
    parser.add_argument("--max-sweeps", type=int, default=10)
    args = parser.parse_args(argv)
    run(args.folder, args.version, args.out, tuple(args.which.split(",")), args.max_sweeps)


if __name__ == "__main__":
    main()
