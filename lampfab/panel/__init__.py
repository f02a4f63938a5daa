"""The flat panel of the source's prior work, the lamp's alternative (``[lens] kind =
"panel"``): its geometry and beam (``geometry``), its design by collimated transport
(``transport``), its checks (``checks``), its STEP solid (``brep``) and what its stages do
differently (``kind``)."""
