"""Three real clients of nuscenes-devkit's `NuScenesCanBus`, restated line for line as functions of the objects they
are given, so that the same lines run on the devkit's `NuScenes` / `NuScenesCanBus` and on nuparquet's.

1. BEVFormer: fundamentalvision/BEVFormer, commit 66b65f3a1f58caf0507cb2a971b9c0e7f842376c (the file is unchanged
   since 68e6af5628211d82261efc328d7d4d5a9ca0cf5f), `tools/data_converter/nuscenes_converter.py`:
   `create_nuscenes_infos` lines 49-52 (`NuScenesCanBus(dataroot=can_bus_root_path)`), `_get_can_bus_info`
   lines 154-176 exactly, and the lines of `_fill_trainval_infos` (178-227) that build each info's head. Left out:
   mmcv's progress bar (a plain loop) and `mmcv.check_file_exist` (`check_files`; the synthetic sets have no lidar
   files), the cameras and sweeps (tests/parity/mmdet3d_converter.py restates that part of the converter family).
2. MapTR v2: hustvl/MapTR, branch maptrv2, commit e03f097abef19e1ba3fed5f471a8d80fbfa0a064,
   `tools/maptrv2/custom_nusc_map_converter.py`: `create_nuscenes_infos` line 778 (`NuScenesCanBus(...)`),
   `_get_can_bus_info` lines 153-175 (BEVFormer's text, character for character), and the head of
   `_fill_trainval_infos` (240-300: `map_location`, `can_bus`, `frame_idx`, ...). Left out as above, and the map
   ground truth (`obtain_vectormap`, the map expansion's client).
3. nuscenes-devkit 1.2.0's own `python-sdk/tutorials/can_bus_tutorial.ipynb` (nutonomy/nuscenes-devkit commit
   d9de17a73bdc06ce97a02f77ae7edb9b0406e851): its code cells in order, the scene name a parameter, each figure
   written to a file instead of shown, printed text captured by the caller.
"""

from __future__ import annotations

import numpy as np


# --- 1. BEVFormer ------------------------------------------------------------------------------------------------

def bevformer_get_can_bus_info(nusc, nusc_can_bus, sample):
    scene_name = nusc.get('scene', sample['scene_token'])['name']
    sample_timestamp = sample['timestamp']
    try:
        pose_list = nusc_can_bus.get_messages(scene_name, 'pose')
    except:  # noqa: E722 - the converter's own bare except
        return np.zeros(18)  # server scenes do not have can bus information.
    can_bus = []
    # during each scene, the first timestamp of can_bus may be large than the first sample's timestamp
    last_pose = pose_list[0]
    for i, pose in enumerate(pose_list):
        if pose['utime'] > sample_timestamp:
            break
        last_pose = pose
    _ = last_pose.pop('utime')  # useless
    pos = last_pose.pop('pos')
    rotation = last_pose.pop('orientation')
    can_bus.extend(pos)
    can_bus.extend(rotation)
    for key in last_pose.keys():
        can_bus.extend(pose[key])  # 16 elements
    can_bus.extend([0., 0.])
    return np.array(can_bus)


def bevformer_infos(nusc, NuScenesCanBus, can_bus_root_path, **can_bus_options) -> list[dict]:
    """The head of each info `_fill_trainval_infos` writes, one per sample of `nusc.sample` in its order."""
    nusc_can_bus = NuScenesCanBus(dataroot=can_bus_root_path, **can_bus_options)
    infos = []
    frame_idx = 0
    for sample in nusc.sample:
        lidar_token = sample['data']['LIDAR_TOP']
        sd_rec = nusc.get('sample_data', sample['data']['LIDAR_TOP'])
        cs_record = nusc.get('calibrated_sensor',
                             sd_rec['calibrated_sensor_token'])
        pose_record = nusc.get('ego_pose', sd_rec['ego_pose_token'])
        lidar_path, boxes, _ = nusc.get_sample_data(lidar_token)

        can_bus = bevformer_get_can_bus_info(nusc, nusc_can_bus, sample)
        ##
        info = {
            'lidar_path': lidar_path,
            'token': sample['token'],
            'prev': sample['prev'],
            'next': sample['next'],
            'can_bus': can_bus,
            'frame_idx': frame_idx,  # temporal related info
            'sweeps': [],
            'cams': dict(),
            'scene_token': sample['scene_token'],  # temporal related info
            'lidar2ego_translation': cs_record['translation'],
            'lidar2ego_rotation': cs_record['rotation'],
            'ego2global_translation': pose_record['translation'],
            'ego2global_rotation': pose_record['rotation'],
            'timestamp': sample['timestamp'],
        }

        if sample['next'] == '':
            frame_idx = 0
        else:
            frame_idx += 1
        infos.append(info)
    return infos


# --- 2. MapTR v2 -------------------------------------------------------------------------------------------------

# `_get_can_bus_info` of custom_nusc_map_converter.py (lines 153-175) is BEVFormer's (lines 154-176) character for
# character (diffed when this was written): the same function.
maptr_get_can_bus_info = bevformer_get_can_bus_info


def maptr_infos(nusc, NuScenesCanBus, can_bus_root_path, **can_bus_options) -> list[dict]:
    """The head of each info MapTR v2's `_fill_trainval_infos` writes, before its cameras, sweeps and map."""
    nusc_can_bus = NuScenesCanBus(dataroot=can_bus_root_path, **can_bus_options)
    infos = []
    frame_idx = 0
    for sample in nusc.sample:
        map_location = nusc.get('log', nusc.get('scene', sample['scene_token'])['log_token'])['location']

        lidar_token = sample['data']['LIDAR_TOP']
        sd_rec = nusc.get('sample_data', sample['data']['LIDAR_TOP'])
        cs_record = nusc.get('calibrated_sensor',
                             sd_rec['calibrated_sensor_token'])
        pose_record = nusc.get('ego_pose', sd_rec['ego_pose_token'])
        lidar_path, boxes, _ = nusc.get_sample_data(lidar_token)

        can_bus = maptr_get_can_bus_info(nusc, nusc_can_bus, sample)
        ##
        info = {
            'lidar_path': lidar_path,
            'token': sample['token'],
            'prev': sample['prev'],
            'next': sample['next'],
            'can_bus': can_bus,
            'frame_idx': frame_idx,  # temporal related info
            'sweeps': [],
            'cams': dict(),
            'map_location': map_location,
            'scene_token': sample['scene_token'],  # temporal related info
            'lidar2ego_translation': cs_record['translation'],
            'lidar2ego_rotation': cs_record['rotation'],
            'ego2global_translation': pose_record['translation'],
            'ego2global_rotation': pose_record['rotation'],
            'timestamp': sample['timestamp'],
        }

        if sample['next'] == '':
            frame_idx = 0
        else:
            frame_idx += 1
        infos.append(info)
    return infos


# --- 3. the devkit's CAN bus tutorial ------------------------------------------------------------------------------

def can_bus_tutorial(NuScenesCanBus, dataroot, scene_name, figures, **can_bus_options) -> dict:
    """The tutorial's cells; `figures(name)` gives the path each figure is written to. Returns what the cells
    compute (the wheel and vehicle speeds, the misaligned routes, the blacklist)."""
    import matplotlib.pyplot as plt

    nusc_can = NuScenesCanBus(dataroot=dataroot, **can_bus_options)

    nusc_can.print_all_message_stats(scene_name)

    message_name = 'steeranglefeedback'
    key_name = 'value'
    nusc_can.plot_message_data(scene_name, message_name, key_name, out_path=figures('steeranglefeedback'))
    plt.close()

    message_name = 'pose'
    key_name = 'accel'
    nusc_can.plot_message_data(scene_name, message_name, key_name, dimension=1, out_path=figures('pose_accel'))
    plt.close()

    # Retrieve raw data.
    wheel_speed = nusc_can.get_messages(scene_name, 'zoe_veh_info')
    wheel_speed = np.array([(m['utime'], m['FL_wheel_speed']) for m in wheel_speed])

    veh_speed = nusc_can.get_messages(scene_name, 'vehicle_monitor')
    veh_speed = np.array([(m['utime'], m['vehicle_speed']) for m in veh_speed])

    # Convert to m/s.
    radius = 0.305  # Known Zoe wheel radius in meters.
    circumference = 2 * np.pi * radius
    wheel_speed[:, 1] *= circumference / 60
    veh_speed[:, 1] *= 1 / 3.6

    # Normalize time.
    wheel_speed[:, 0] = (wheel_speed[:, 0] - wheel_speed[0, 0]) / 1e6
    veh_speed[:, 0] = (veh_speed[:, 0] - veh_speed[0, 0]) / 1e6

    plt.plot(wheel_speed[:, 0], wheel_speed[:, 1])
    plt.plot(veh_speed[:, 0], veh_speed[:, 1])
    plt.xlabel('Time in s')
    plt.ylabel('Speed in m/s')
    plt.legend(['Wheel speed', 'Vehicle speed']);  # noqa: E703 - the notebook's
    plt.savefig(figures('speeds'))
    plt.close()

    nusc_can.plot_baseline_route(scene_name, out_path=figures('baseline_route'))
    plt.close()

    print(nusc_can.list_misaligned_routes())

    print(nusc_can.can_blacklist)
    return {"wheel_speed": wheel_speed, "veh_speed": veh_speed, "misaligned": nusc_can.list_misaligned_routes(),
            "can_blacklist": nusc_can.can_blacklist}
