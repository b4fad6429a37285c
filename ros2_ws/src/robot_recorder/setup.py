from setuptools import find_packages, setup

package_name = "robot_recorder"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{package_name}"]),
        (f"share/{package_name}", ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="efficient_comm dev",
    maintainer_email="dev@example.com",
    description="On-robot recording to MCAP off the callback path, remote control, playback.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "recorder = robot_recorder.cli:record_main",
            "player = robot_recorder.cli:play_main",
        ],
        "efficient_comm.components": [
            "Recorder = robot_recorder.recorder:Recorder",
            "Player = robot_recorder.player:Player",
        ],
    },
)
