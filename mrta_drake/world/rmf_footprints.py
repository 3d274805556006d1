"""Footprints of the Gazebo Fuel models placed in the Open-RMF demo buildings.

Each entry is the model's name after the owner ("OpenRobotics/Desk" -> "Desk") and its
footprint in its own frame: ``(sx, sy)`` m for a box (x along the model's yaw), a single
radius (m) for a cylinder, or None for models that are not obstacles to a robot: workcells
robots hand items to, a whole-site mesh. Sizes are estimates from the models' look (not
measured from their meshes), within about 10 cm for furniture. A model not listed becomes a
cylinder of ``BuildingWorldParams.model_radius``.
"""

FOOTPRINTS: dict[str, tuple[float, float] | float | None] = {
    # Workcells and site meshes: not obstacles.
    "TeleportDispenser": None, "TeleportIngestor": None, "Campus": None,
    # Office furniture.
    "AdjTable": (1.6, 0.8), "Desk": (1.4, 0.7), "MainTable": (1.8, 0.9), "Table": (1.2, 0.8),
    "ConfTable": (3.0, 1.2), "CoffeeTable": (1.0, 0.6), "Cafe table": 0.4,
    "FoodCourtTable1": (1.2, 1.2), "FoodCourtBenchShort": (1.2, 0.4),
    "SmallCubicle": (1.6, 1.6), "BigCubicle": (2.5, 2.5), "NurseDesk": (2.0, 0.8),
    "NurseTable": (1.2, 0.6), "Drawer": (0.5, 0.6), "Bookshelf": (0.9, 0.4),
    "MetalCabinet": (0.9, 0.5), "MetalCabinetYellow": (0.9, 0.5), "WhiteCabinet": (0.8, 0.5),
    "SquareShelf": (0.8, 0.8), "StorageRack": (1.2, 0.5), "HeadphonesRack1": (0.5, 0.5),
    "ElectronicsRecycling": (0.8, 0.6), "MonitorAndKeyboard": (0.6, 0.3),
    "VendingMachine": (1.0, 0.8), "Fridge": (0.7, 0.7), "DigitalKiosk": (0.6, 0.5),
    "Cafe": (3.0, 2.0),
    # Seats.
    "Chair": 0.25, "DeskChair": 0.3, "OfficeChairBlack": 0.3, "OfficeChairBlue": 0.3,
    "OfficeChairGrey": 0.3, "PotatoChipChair": 0.3, "WhiteChipChair": 0.3,
    "WoodenChair": 0.25, "MiniSofa": (1.0, 0.8), "Sofa": (2.0, 0.9),
    # Home and hospital.
    "NormalBed": (2.1, 1.0), "BedsideTable": (0.5, 0.4), "KitchenCountertop": (2.0, 0.6),
    "KitchenSink": (1.0, 0.6), "BathroomSink": (0.6, 0.5), "Toilet": (0.7, 0.4),
    "Shower": (0.9, 0.9), "IVStand": 0.25, "SurgicalTrolleyMed": (0.8, 0.5),
    "PatientWheelChair": (1.0, 0.65), "CGMVanguard": (0.6, 0.6), "LampAndStand": 0.25,
    "TrashBin": 0.25, "LitterBin": 0.25,
    # People standing or sitting still.
    "Standing person": 0.25, "Nurse": 0.25, "Scrubs": 0.25, "OpScrubs": 0.25,
    "FemaleVisitor": 0.25, "MaleVisitorOnPhone": 0.25, "ElderLadyPatient": 0.25,
    "ElderMalePatient": 0.25, "FemaleVisitorSit": 0.35, "MaleVisitorSit": 0.35,
    "PatientFSit": 0.35, "VisitorKidSit": 0.3,
    # Airport and outdoors.
    "Suitcase1": 0.3, "Suitcase2": 0.3, "ParkingTrolleyMax": (1.2, 0.6), "MopCart2": (1.0, 0.5),
    "MopCart3": (1.0, 0.5), "Fountain": (0.5, 0.4), "EscalatorStart": (1.5, 1.2),
    "Construction Cone": 0.2, "Lamp Post": 0.15, "Oak tree": 0.4, "Pine Tree": 0.3,
    "SUV": (4.8, 1.9), "Ambulance2": (6.0, 2.3), "Gazebo": (4.0, 4.0), "Playground": (6.0, 6.0),
}


def footprint(model_name: str):
    """The footprint of Fuel model ``model_name`` ("Owner/Model" or "Model"): (sx, sy) m,
    a radius (m), None (no obstacle), or KeyError when unknown."""
    return FOOTPRINTS[model_name.rsplit("/", 1)[-1]]
