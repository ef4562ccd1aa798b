"""The pursuers' directional radio: the conic antenna that both detects and jams (Eqs. 9-10),
and the range/azimuth/inclination measurements it returns (Eqs. 6-8)."""
