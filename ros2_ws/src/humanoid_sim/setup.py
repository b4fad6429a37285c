from setuptools import find_packages, setup

package_name = "humanoid_sim"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["models/*.xml", "py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{package_name}"]),
        (f"share/{package_name}", ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="efficient_comm dev",
    maintainer_email="dev@example.com",
    description="MuJoCo behind emulated Dynamixel servos: a simulated kid-size soccer humanoid.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "soccer_demo = humanoid_sim.demo:main",
            "simulator = humanoid_sim.simulator:main",
            "world = humanoid_sim.world_simulator:main",
            "servo_driver = humanoid_sim.driver:main",
            "match_log = humanoid_sim.match_log:main",
        ],
        "efficient_comm.components": [
            "humanoid_sim::Simulator = humanoid_sim.simulator:Simulator",
            "humanoid_sim::WorldSimulator = humanoid_sim.world_simulator:WorldSimulator",
            "humanoid_sim::ServoDriver = humanoid_sim.driver:ServoDriver",
            "humanoid_sim::BallDetector = humanoid_sim.soccer.vision:BallDetector",
            "humanoid_sim::BlobBallDetector = humanoid_sim.soccer.vision:BlobBallDetector",
            "humanoid_sim::BallModel = humanoid_sim.soccer.world_model:BallModel",
            "humanoid_sim::HeadBehaviour = humanoid_sim.soccer.behaviour:HeadBehaviour",
            "humanoid_sim::MotionArbiter = humanoid_sim.soccer.arbiter:MotionArbiter",
            "humanoid_sim::Kick = humanoid_sim.soccer.kick:Kick",
            "humanoid_sim::SoccerMonitor = humanoid_sim.soccer.monitor:SoccerMonitor",
            "humanoid_sim::FallDetector = humanoid_sim.soccer.fall:FallDetector",
            "humanoid_sim::WalkEngine = humanoid_sim.soccer.walk:WalkEngine",
            "humanoid_sim::GetUp = humanoid_sim.soccer.getup:GetUp",
            "humanoid_sim::TeamComm = humanoid_sim.soccer.team_comm:TeamComm",
            "humanoid_sim::TeamReferee = humanoid_sim.soccer.team_referee:TeamReferee",
        ],
    },
)
