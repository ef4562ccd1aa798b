"""The physical world: the surveillance area, the pursuers' kinematics (Eq. 3) and the truth
target (Eq. 1 and its existence)."""
