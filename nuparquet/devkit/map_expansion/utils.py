"""The devkit's `nuscenes.map_expansion.utils`: the lane graph's disconnected parts and the ego poses' share on the
drivable area, its code over a `NuScenesMap` (ours or the devkit's) and a `NuScenes` (ours or the devkit's).

`drop_disconnected_lanes` changes the record lists and dicts in memory, as the devkit's does; the spatial queries
of our `NuScenesMap` keep answering from the converted map (`get_closest_lane` may still name a dropped lane).
"""

from __future__ import annotations

from typing import Dict, List, Set


def get_egoposes_on_drivable_ratio(nusc, nusc_map, scene_token: str) -> float:
    """The share of the scene's keyframe LIDAR_TOP ego poses that lie on a drivable area."""
    sample_tokens = nusc.field2token('sample', 'scene_token', scene_token)
    poses_all = 0
    poses_valid = 0
    for sample_token in sample_tokens:
        sample_record = nusc.get('sample', sample_token)
        sample_data_record = nusc.get('sample_data', sample_record['data']['LIDAR_TOP'])
        pose_record = nusc.get('ego_pose', sample_data_record['ego_pose_token'])

        ego_pose = pose_record['translation'][:2]
        record = nusc_map.record_on_point(ego_pose[0], ego_pose[1], 'drivable_area')
        if len(record) > 0:
            poses_valid += 1
        poses_all += 1
    ratio_valid = poses_valid / poses_all

    return ratio_valid


def get_disconnected_subtrees(connectivity: Dict[str, dict]) -> Set[str]:
    """The lanes not reachable from the first lane of `connectivity` through incoming or outgoing links."""
    connected = set()
    pending = set()

    all_keys = list(connectivity.keys())
    first_key = all_keys[0]
    all_keys = set(all_keys)
    pending.add(first_key)

    while len(pending) > 0:
        lane_token = pending.pop()
        connected.add(lane_token)

        if lane_token in connectivity:
            incoming = connectivity[lane_token]['incoming']
            outgoing = connectivity[lane_token]['outgoing']
            inout_lanes = set(incoming + outgoing)
            for other_lane_token in inout_lanes:
                if other_lane_token not in connected:
                    pending.add(other_lane_token)

    disconnected = all_keys - connected
    assert len(disconnected) < len(connected), 'Error: Bad initialization chosen!'
    return disconnected


def drop_disconnected_lanes(nusc_map):
    """Remove the disconnected lanes and lane connectors from the map's records (in memory) and return the map."""
    disconnected = get_disconnected_lanes(nusc_map)

    nusc_map.lane = [lane for lane in nusc_map.lane if lane['token'] not in disconnected]
    nusc_map.lane_connector = [lane for lane in nusc_map.lane_connector if lane['token'] not in disconnected]

    for lane_token in disconnected:
        if lane_token in nusc_map.connectivity:
            del nusc_map.connectivity[lane_token]

    for lane_token in disconnected:
        if lane_token in nusc_map.arcline_path_3:
            del nusc_map.arcline_path_3[lane_token]

    empty_connectivity = []
    for lane_token, connectivity in nusc_map.connectivity.items():
        connectivity['incoming'] = [i for i in connectivity['incoming'] if i not in disconnected]
        connectivity['outgoing'] = [o for o in connectivity['outgoing'] if o not in disconnected]
        if len(connectivity['incoming']) + len(connectivity['outgoing']) == 0:
            empty_connectivity.append(lane_token)
    for lane_token in empty_connectivity:
        del nusc_map.connectivity[lane_token]

    # To fix the map class, we need to update some indices.
    nusc_map._make_token2ind()

    return nusc_map


def get_disconnected_lanes(nusc_map) -> List[str]:
    """Sorted tokens of the lanes without links, linked lanes that are no records, and disconnected subtrees."""
    disconnected = set()
    for lane_token, connectivity in nusc_map.connectivity.items():
        inout_lanes = connectivity['incoming'] + connectivity['outgoing']
        if len(inout_lanes) == 0:
            disconnected.add(lane_token)
            continue

        for inout_lane_token in inout_lanes:
            if inout_lane_token not in nusc_map._token2ind['lane'] and \
                    inout_lane_token not in nusc_map._token2ind['lane_connector']:
                disconnected.add(inout_lane_token)

    subtrees = get_disconnected_subtrees(nusc_map.connectivity)
    disconnected = disconnected.union(subtrees)

    return sorted(list(disconnected))
